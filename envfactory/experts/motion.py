"""From a wanted EE pose to the env's own action: the shared core of every scripted expert.

Experts plan in Cartesian space and emit what a learner would: joint
deltas from IK in joint mode, EE deltas in EE mode, always inside the
action box and the per-step joint-change limit, so no expert action is
clipped or rejected for size.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from envfactory.geometry.frames import nearest_top_down

AXES = {"x": 0, "y": 1, "z": 2}


def shrink_into(vector: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Scale a step down uniformly so it fits the box, keeping its direction."""
    limit = np.where(vector >= 0, high, -low)
    ratio = np.max(np.abs(vector) / np.maximum(limit, 1e-9))
    return vector / ratio if ratio > 1.0 else vector


def vertical_turn(relative: np.ndarray) -> float:
    """The angle, rad, by which a rotation turns the horizontal x axis about the vertical: the whole of a turn
    between two top-down orientations."""
    return float(np.arctan2(relative[1, 0], relative[0, 0]))


class ArmMotion:
    def __init__(self, env):
        self.env = env
        spec = env.blueprint.spec
        self.layout = env.blueprint.action
        self.max_joint_delta = 0.9 * spec.env.safety.max_joint_delta
        robot = spec.robot
        self.gripper = robot.gripper
        self.down = pin.rpy.rpyToMatrix(*robot.top_down_rpy) if robot.top_down_rpy is not None else None
        self.closing_axis = AXES[robot.gripper.closing_axis] if robot.gripper is not None else 1

    # ------------------------------------------------------------ orientation

    def down_facing(self, direction_xy: np.ndarray) -> np.ndarray | None:
        """Top-down orientation whose finger-closing axis lies along `direction_xy` (either sign):
        the fingers are symmetric, so a half turn gives the same grip."""
        return self._closing_axis_at(np.arctan2(direction_xy[1], direction_xy[0]), period=np.pi)

    def square_to(self, yaw: float) -> np.ndarray | None:
        """Top-down orientation that closes the fingers on two opposite faces of a box turned by
        `yaw`: a box has four faces to close on, so a quarter turn gives the same grip."""
        return self._closing_axis_at(yaw, period=np.pi / 2)

    def _closing_axis_at(self, yaw: float, period: float) -> np.ndarray | None:
        """Top-down orientation with the closing axis at `yaw` (modulo `period`), turned as
        little as possible from the current orientation; None if the robot declares no top-down pose."""
        if self.down is None:
            return None
        return nearest_top_down(self.down, self.env.state.ee_rotation, self.closing_axis, yaw, period)

    # ------------------------------------------------------------ actions

    def toward(
        self,
        target: np.ndarray,
        rotation: np.ndarray | None = None,
        gripper: float | None = None,
        max_step: float = 0.03,
        max_turn: float = 0.3,
    ) -> np.ndarray:
        """One action moving the EE at most `max_step` along the straight line to `target`,
        turning it at most `max_turn` rad toward `rotation`."""
        env, layout = self.env, self.layout
        state = env.state
        offset = np.asarray(target, float) - state.ee_position
        distance = np.linalg.norm(offset)
        if distance > max_step:
            offset *= max_step / distance
        waypoint = state.ee_position + offset
        if rotation is not None:
            # small turns keep each IK solve near the current pose, so the path stays straight
            turn = pin.log3(rotation @ state.ee_rotation.T)
            angle = np.linalg.norm(turn)
            if angle > max_turn:
                rotation = pin.exp3(turn * (max_turn / angle)) @ state.ee_rotation
        arm_size = layout.size - (1 if layout.gripper_in_action else 0)
        low, high = layout.low[:arm_size], layout.high[:arm_size]
        if layout.ee:
            wanted = offset / layout.delta_coeff if layout.delta else waypoint
            if layout.yaw:
                # the turn's part about the vertical, as far as the Δyaw row reaches; the rest is the adapter's
                turn = 0.0 if rotation is None else vertical_turn(rotation @ state.ee_rotation.T)
                yaw_row = float(np.clip(turn / layout.delta_coeff, low[3], high[3]))
                low, high = low[:3], high[:3]
        else:
            solution = env.kinematics.solve_ik(
                state.q_arm, waypoint, target_rotation=rotation, gripper=state.gripper, rotation_weight=1.0
            )
            step = solution.q_arm - state.q_arm
            largest = np.max(np.abs(step))
            if largest > self.max_joint_delta:
                step *= self.max_joint_delta / largest
            wanted = step / layout.delta_coeff if layout.delta else state.q_arm + step
        if layout.delta:
            wanted = shrink_into(wanted, low, high)
        if layout.yaw:
            wanted = np.append(wanted, yaw_row)
        if layout.gripper_in_action:
            value = state.gripper if gripper is None else gripper
            wanted = np.append(wanted, value)
        return env.actions.to_policy(wanted)


class Expert:
    """A scripted policy: `Params` validates its YAML params; `reset` runs after every env reset."""

    Params: type = None

    @classmethod
    def check(cls, params, spec) -> list[tuple[str, str]]:
        """(param, message) for each param the robot or task contradicts; the compiler reports them."""
        return []

    @classmethod
    def working_points(cls, params, spec) -> list:
        """The EE points (experts.points.ExpertPoint) this expert must reach for the task; the compiler checks
        them against the workspace, the reach and the safety margin. None for an expert that works at the goal
        itself, which the goal checks cover."""
        return []

    def __init__(self, env, params):
        self.env = env
        self.params = params
        self.motion = ArmMotion(env)
        self.reset()

    def reset(self) -> None:
        pass
