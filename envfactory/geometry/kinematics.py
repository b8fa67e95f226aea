"""Pinocchio kinematics of one robot: FK of every link, IK and Jacobians.

Sim and real share this code, so an action is judged by the same geometry
whichever backend executes it. Positions are in the task frame (world for the
UR5e, the robot base for the VX300S). The model itself is built in the world's
axes at the base origin, with the base orientation (`mount_rpy`) in it, so the
collision geometry that rides on it is placed as the real base is.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from envfactory.geometry.frames import TaskFrame, base_rotation, place_base
from envfactory.geometry.kernels.joint_table import JointTable
from envfactory.geometry.kernels.serving import kernels
from envfactory.schema.models import RobotSpec


def quaternion_to_matrix(quaternion) -> np.ndarray:
    """Rotation matrix of an (x, y, z, w) quaternion, the order PyBullet and ROS use."""
    x, y, z, w = quaternion
    return pin.Quaternion(w, x, y, z).normalized().toRotationMatrix()


_NO_ROTATION = np.eye(3)  # what the IK kernel is passed when no orientation is asked for (it reads none)


@dataclass(frozen=True)
class IkResult:
    q_arm: np.ndarray
    success: bool
    position_error: float


class Kinematics:
    """Pinocchio FK, Jacobians and damped least-squares IK of one robot, in the task frame. Holds its own
    pinocchio data (a measuring copy per env), so it is not shared between threads."""

    def __init__(self, urdf_path: Path, robot: RobotSpec, task_frame: TaskFrame | None = None):
        """`task_frame`: where results are expressed; None for the model's own frame."""
        self.robot = robot
        self.urdf_path = Path(urdf_path)
        self.model = pin.buildModelFromUrdf(str(urdf_path))
        self.base_rotation = base_rotation(robot)
        place_base(self.model, self.base_rotation)
        self.data = self.model.createData()
        to_task = task_frame.base_in_task(robot) if task_frame is not None else pin.SE3.Identity()
        self.base_in_task = to_task.translation.copy()
        # the task frame's axes against the model's: None when they agree (every shipped robot),
        # so those positions stay a bare sum
        self._task_rotation = None if np.array_equal(to_task.rotation, np.eye(3)) else to_task.rotation.copy()
        self._arm_q = np.array([self._q_index(j.name) for j in robot.arm_joints])
        self.arm_lower = np.array([j.lower for j in robot.arm_joints])
        self.arm_upper = np.array([j.upper for j in robot.arm_joints])
        self._gripper_q: np.ndarray = np.zeros(0, dtype=int)
        self._gripper_gain: np.ndarray = np.zeros(0)
        if robot.gripper is not None:
            followers = [(robot.gripper.joint, 1.0), *robot.gripper.mimic.items()]
            self._gripper_q = np.array([self._q_index(name) for name, _ in followers])
            self._gripper_gain = np.array([gain for _, gain in followers])
        self.ee_frame = self._frame_id(robot.ee_frame)
        self._q = pin.neutral(self.model)
        # the tree as the compiled kernels pose it (the collision model's too), and the EE's chain in it
        self.joint_table = JointTable(self.model, self.coordinate_drivers())
        ee = self.model.frames[self.ee_frame]
        chain, joint = [], ee.parentJoint
        while joint > 0:
            chain.append(joint)
            joint = self.model.parents[joint]
        self._ee_chain = np.array(chain[::-1], dtype=np.int64)
        self._ee_placement = np.ascontiguousarray(ee.placement.homogeneous[:3])

    def measuring_copy(self) -> "Kinematics":
        """A copy sharing the model and every table, with scratch state of its own (Pinocchio's data and the
        configuration buffer), so that users of one shared chain never overwrite each other's results."""
        twin = copy.copy(self)
        twin.data = self.model.createData()
        twin._q = pin.neutral(self.model)
        return twin

    # ----------------------------------------------------------- lookups

    def _q_index(self, joint_name: str) -> int:
        if not self.model.existJointName(joint_name):
            known = [self.model.names[i] for i in range(1, self.model.njoints)]
            raise ValueError(f"robot {self.robot.name!r}: the URDF has no joint {joint_name!r} (joints: {known})")
        joint = self.model.joints[self.model.getJointId(joint_name)]
        if joint.nq != 1:
            raise ValueError(f"robot {self.robot.name!r}: joint {joint_name!r} must have one degree of freedom")
        return joint.idx_q

    def _frame_id(self, frame_name: str) -> int:
        if not self.model.existFrame(frame_name):
            raise ValueError(f"robot {self.robot.name!r}: the URDF has no frame {frame_name!r}")
        return self.model.getFrameId(frame_name)

    def coordinate_drivers(self) -> dict[int, tuple[int, float]]:
        """Which coordinate moves each driven joint, and how much: joint id -> (coordinate, gain).
        Coordinates are the arm joints in action order, then the gripper."""
        drivers = {self.model.getJointId(j.name): (index, 1.0) for index, j in enumerate(self.robot.arm_joints)}
        if self.robot.gripper is not None:
            gripper = len(self.robot.arm_joints)
            for name, gain in [(self.robot.gripper.joint, 1.0), *self.robot.gripper.mimic.items()]:
                drivers[self.model.getJointId(name)] = (gripper, gain)
        return drivers

    # ----------------------------------------------------------- configuration

    def full_q(self, q_arm: np.ndarray, gripper: float = 0.0) -> np.ndarray:
        q = self._q
        q[self._arm_q] = q_arm
        if self._gripper_q.size:
            q[self._gripper_q] = self._gripper_gain * gripper
        return q

    # ----------------------------------------------------------- frames

    def to_task(self, point: np.ndarray) -> np.ndarray:
        """A point of the model's frame in the task frame."""
        if self._task_rotation is None:
            return point + self.base_in_task
        return self._task_rotation @ point + self.base_in_task

    def _rotation_to_task(self, rotation: np.ndarray) -> np.ndarray:
        return rotation.copy() if self._task_rotation is None else self._task_rotation @ rotation

    # ----------------------------------------------------------- forward kinematics

    def ee_pose(self, q_arm: np.ndarray, gripper: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """EE position (task frame) and rotation matrix."""
        pin.forwardKinematics(self.model, self.data, self.full_q(q_arm, gripper))
        placement = pin.updateFramePlacement(self.model, self.data, self.ee_frame)
        return self.to_task(placement.translation), self._rotation_to_task(placement.rotation)

    # ----------------------------------------------------------- inverse kinematics

    def solve_ik(
        self,
        q_arm_start: np.ndarray,
        target_position: np.ndarray,
        target_rotation: np.ndarray | None = None,
        gripper: float = 0.0,
        rotation_weight: float = 0.5,
        max_iterations: int = 150,
        tolerance: float = 5e-4,
        damping: float = 1e-2,
    ) -> IkResult:
        """Damped least squares on the arm joints, within their bounds.

        Orientation is a soft objective: success is judged on position alone,
        so a target the wrist cannot reach at the asked orientation still
        resolves to the nearest pose that puts the EE on the point. Each
        iteration steps by damped least squares from the clamped start
        (at most 0.3 a joint, then held within the bounds): on position and
        the weighted orientation error stacked, or, on an arm of fewer than
        six joints, on position first and the orientation in what is left.
        It stops on the point (with the orientation reached or no longer
        improving), after five iterations that do not close in, or at
        max_iterations. Compiled whole (kernels/inverse_kinematics.py).
        """
        target_position = np.asarray(target_position, dtype=float) - self.base_in_task
        if self._task_rotation is not None:  # into the model's frame, where the Jacobian is
            target_position = self._task_rotation.T @ target_position
            if target_rotation is not None:
                target_rotation = self._task_rotation.T @ target_rotation
        table = self.joint_table
        q_arm = np.empty(self.arm_lower.size)
        error = kernels.solve_ik(
            np.ascontiguousarray(q_arm_start, dtype=float),
            self.arm_lower,
            self.arm_upper,
            float(gripper),
            np.ascontiguousarray(target_position),
            _NO_ROTATION if target_rotation is None else np.ascontiguousarray(target_rotation, dtype=float),
            target_rotation is not None,
            float(rotation_weight),
            int(max_iterations),
            float(tolerance),
            float(damping),
            self._ee_chain,
            table.parent,
            table.placement,
            table.kind,
            table.axis,
            table.coordinate,
            table.gain,
            self._ee_placement,
            q_arm,
        )
        return IkResult(q_arm, error < tolerance, error)
