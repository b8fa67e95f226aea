"""Boxes that hold every point an observation reports, derived from the robot and the scene.

The reference pages declare an EE box (`robot.ee_bounds`) that the arm can leave: the UR5e's
TCP reaches 2.0 m above the floor where the box ends at 1.5 m. The observation
bounds therefore use that box grown to the arm's reach, never shrunk:

- reach: no point of the EE frame lies farther from the first joint's origin than
  the sum of the offsets along the kinematic chain (each joint's offset from its
  parent joint, the EE frame's from its joint, plus the travel of any prismatic
  joint), whatever the joint angles; the box of that sphere, above the floor.
- objects: carried or pushed by the gripper (the EE box grown by the object's
  half diagonal), resting on the table, or fallen to the floor.
- joint positions: the declared /joint_states range, or the URDF's limits where
  those are wider (a position motor holds its target only up to the load on it;
  the hard stop is the URDF limit, which PyBullet enforces as a constraint that
  yields by up to JOINT_STOP_SOFTNESS).
- joint velocities: the declared /joint_states range, or the URDF's velocity
  limits where those are wider (contact drives a joint past its motor's speed:
  the UR5e knuckle read 0.59 rad/s against its motor's 0.45 while a cube was
  knocked about).
- finite-difference velocities: a displacement within the object box over one
  step (`action_cycle_time`), a rotation of at most π over one step.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from envfactory.geometry.frames import TaskFrame
from envfactory.geometry.obstacles import FLOOR_HALF_EXTENT, table_bounds_xy
from envfactory.geometry.robot_model import robot_chain

JOINT_STOP_SOFTNESS = 0.005  # rad or m past a URDF limit a joint pressed against its stop may read


@dataclass(frozen=True)
class Box:
    low: np.ndarray
    high: np.ndarray

    def union(self, other: "Box") -> "Box":
        return Box(np.minimum(self.low, other.low), np.maximum(self.high, other.high))

    def grown(self, margin: float) -> "Box":
        return Box(self.low - margin, self.high + margin)

    @property
    def extent(self) -> np.ndarray:
        return self.high - self.low

    def farthest_from(self, other: "Box") -> float:
        """The largest distance between a point of this box and a point of the other."""
        return float(np.linalg.norm(np.maximum(self.high - other.low, other.high - self.low)))


@dataclass(frozen=True)
class PointBoxes:
    """Where the EE and each object can be (task frame), and how long a step is."""

    ee: Box
    objects: dict[str, Box] = field(default_factory=dict)
    step_seconds: float = 0.5
    joint_positions: Box | None = None  # one row per /joint_states entry
    joint_velocities: Box | None = None

    def of(self, name: str) -> Box:
        return self.ee if name == "ee" else self.objects[name]

    def linear_speed(self, name: str) -> np.ndarray:
        return self.of(name).extent / self.step_seconds

    @property
    def angular_speed(self) -> float:
        return float(np.pi / self.step_seconds)


def reach_sphere(kinematics) -> tuple[np.ndarray, float]:
    """(centre in the task frame, radius) of a sphere the EE frame never leaves."""
    model = kinematics.model
    frame = model.frames[kinematics.ee_frame]
    chain = []
    joint = frame.parentJoint
    while joint > 0:
        chain.append(joint)
        joint = model.parents[joint]
    if not chain:  # an EE fixed to the base: a point
        data = model.createData()
        pin.framesForwardKinematics(model, data, pin.neutral(model))
        return kinematics.to_task(data.oMf[kinematics.ee_frame].translation), 0.0
    first = chain[-1]
    radius = float(np.linalg.norm(frame.placement.translation))
    for joint in chain:
        if joint != first:
            radius += float(np.linalg.norm(model.jointPlacements[joint].translation))
        if model.joints[joint].shortname().startswith("JointModelP"):  # a slide adds its travel
            index = model.joints[joint].idx_q
            radius += float(max(abs(model.lowerPositionLimit[index]), abs(model.upperPositionLimit[index])))
    data = model.createData()
    pin.forwardKinematics(model, data, pin.neutral(model))
    return kinematics.to_task(data.oMi[first].translation), radius


def point_boxes(spec, kinematics, fixtures=None) -> PointBoxes:
    robot = spec.robot
    frame = TaskFrame.of(robot)
    origin = frame.origin
    floor_z = float(0.0 - origin[2])  # a rotated task frame turns about z only: heights stay heights
    ee = Box(*(np.asarray(b, float) for b in robot.ee_bounds))
    if kinematics is not None:
        centre, radius = reach_sphere(kinematics)
        reach_low = centre - radius
        reach_low[2] = max(reach_low[2], floor_z)  # the safety check keeps the gripper above the floor
        ee = ee.union(Box(reach_low, centre + radius))
    table_min, table_max = table_bounds_xy(spec.scene.table, frame)
    top = spec.scene.table.top_z - origin[2]
    objects = {}
    for name, obj in spec.task.objects.items():
        half_diagonal = obj.bounding_radius
        on_table = Box(np.array([*table_min, top]), np.array([*table_max, top + half_diagonal]))
        box = ee.grown(half_diagonal).union(on_table)
        box.low[2] = min(box.low[2], floor_z)  # knocked off the table onto the floor
        if not spec.task.goal.within_reach:
            # an object the task sends off on its own (a struck puck) may leave the table's far edge and come
            # to rest anywhere on the floor
            box = box.union(_floor_box(frame, floor_z, top + half_diagonal))
        objects[name] = box
    for name, fixture in (fixtures or {}).items():
        # a fixture's point moves only along its joint's travel
        ends = np.array([frame.to_task(fixture.point_at(v)) for v in (fixture.lower, fixture.upper)])
        objects[name] = Box(ends.min(axis=0), ends.max(axis=0)).grown(JOINT_STOP_SOFTNESS)
    return PointBoxes(ee, objects, spec.env.timing.action_cycle_time, *_joint_boxes(robot, kinematics))


def _floor_box(frame: TaskFrame, floor_z: float, top: float) -> Box:
    """The floor's extent in the task frame (its corners' box, should the frame turn), from the floor to `top`."""
    corners = np.array(
        [
            frame.to_task(np.array([sx * FLOOR_HALF_EXTENT, sy * FLOOR_HALF_EXTENT, 0.0]))
            for sx in (-1, 1)
            for sy in (-1, 1)
        ]
    )
    return Box(np.array([*corners[:, :2].min(axis=0), floor_z]), np.array([*corners[:, :2].max(axis=0), top]))


def _joint_boxes(robot, kinematics) -> tuple[Box, Box]:
    """(positions, velocities) of the /joint_states entries."""
    positions, velocities = (
        Box(*(np.array([getattr(entry, kind)[i] for entry in robot.joint_states], float) for i in (0, 1)))
        for kind in ("position", "velocity")
    )
    if kinematics is None:
        return positions, velocities
    model = kinematics.model
    joints = [model.joints[model.getJointId(entry.urdf_joint)] for entry in robot.joint_states]
    rows = [joint.idx_q for joint in joints]
    stops = Box(model.lowerPositionLimit[rows], model.upperPositionLimit[rows]).grown(JOINT_STOP_SOFTNESS)
    speed = model.velocityLimit[[joint.idx_v for joint in joints]]
    return positions.union(stops), velocities.union(Box(-speed, speed))


def derived_boxes(spec, asset_root, fixtures=None) -> PointBoxes:
    """The boxes of a spec's robot; the declared EE box alone when the robot model does not load
    (the compiler's robot checks then name what is wrong, and nothing is built from these)."""
    try:
        _, kinematics = robot_chain(spec, asset_root)
        return point_boxes(spec, kinematics, fixtures)
    except Exception:  # a model or a joint name that does not resolve: the robot model checks report it
        return point_boxes(spec, None, fixtures)
