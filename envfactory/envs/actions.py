"""Turns a policy action into a joint target, saying what it had to change.

Out-of-bounds values are clipped and flagged (the joint-limits penalty);
actions that cannot be executed safely are rejected (the none-exe penalty)
and never reach the backend.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from envfactory.compiler import ActionLayout
from envfactory.geometry.frames import nearest_top_down
from envfactory.geometry.kinematics import Kinematics
from envfactory.schema.models import RobotSpec, Workspace
from envfactory.step_state import EnvState

TURN_PER_STEP = 0.3  # rad: how far one EE-mode step turns the tool toward its declared orientation


def _clamp(values, low, high):
    """np.clip, less the dispatch layers it goes through before the arithmetic (a few microseconds a step
    for the four clamps of an action)."""
    return np.minimum(np.maximum(values, low), high)


@dataclass(frozen=True)
class Command:
    q_arm: np.ndarray | None  # None: the action is rejected, the arm holds
    gripper: float | None
    out_of_bounds: bool
    rejection: str = ""
    recorded: np.ndarray | None = None  # the action as the next observation's previous_action reports it


class ActionAdapter:
    def __init__(
        self,
        layout: ActionLayout,
        kinematics: Kinematics,
        workspace: Workspace,
        max_joint_delta: float,
        robot: RobotSpec,
    ):
        self.layout = layout
        # EE mode keeps the tool pointing down (about as far round as it is) or as it is now
        self.top_down = pin.rpy.rpyToMatrix(*robot.top_down_rpy) if robot.ee_mode_orientation == "top_down" else None
        self.closing_axis = "xyz".index(robot.gripper.closing_axis) if robot.gripper is not None else 1
        self.max_joint_delta = max_joint_delta
        self.kinematics = kinematics
        self.low, self.high = layout.low, layout.high
        self.scale = layout.scale if layout.normalize else None
        self.workspace_min = np.asarray(workspace.min, float)
        self.workspace_max = np.asarray(workspace.max, float)
        self.arm_size = layout.size - (1 if layout.gripper_in_action else 0)
        self.policy_low = layout.policy_low.astype(np.float32)
        self.policy_high = layout.policy_high.astype(np.float32)

    def to_policy(self, action: np.ndarray) -> np.ndarray:
        """An action in the spec's units as the policy's action space has it."""
        action = _clamp(action, self.low, self.high)
        return (self.scale.to_policy(action) if self.scale is not None else action).astype(np.float32)

    def hold_action(self, state: EnvState) -> np.ndarray:
        """The action that keeps the robot where it is: the previous action a reset reports."""
        if self.layout.delta:
            arm = np.zeros(self.arm_size)
        else:
            arm = state.ee_position if self.layout.ee else state.q_arm
        return self.to_policy(np.append(arm, state.gripper) if self.layout.gripper_in_action else arm)

    def translate(self, action: np.ndarray, state: EnvState) -> Command:
        """The command an action of the layout's size (the env checked its shape) asks for."""
        if not np.isfinite(action).all():
            return Command(None, None, False, "non-finite action", self.hold_action(state))
        action = np.asarray(action, dtype=float)
        # Flagged only outside the advertised float32 space: its bound may round past the declared row
        # (3.14 is 3.1400001 in float32), and a policy saturated on it asks for nothing the row forbids.
        inside = _clamp(action, self.policy_low, self.policy_high)
        out_of_bounds = bool((inside != action).any())
        # the bounds are float32 numbers: rounding the clamped action is clamping the rounded one
        recorded = inside.astype(np.float32)
        return self._command(inside, state, out_of_bounds, recorded)

    def _command(self, inside: np.ndarray, state: EnvState, out_of_bounds: bool, recorded: np.ndarray) -> Command:
        """The command of a finite action held to the policy's space."""
        action = self.scale.to_seed(inside) if self.scale is not None else inside
        action = _clamp(action, self.low, self.high)  # that rounding, taken back
        gripper = float(action[-1]) if self.layout.gripper_in_action else None
        arm = action[: self.arm_size]
        if self.layout.ee:
            return self._ee_target(arm, state, gripper, out_of_bounds, recorded)
        target = state.q_arm + self.layout.delta_coeff * arm if self.layout.delta else arm
        bounded = _clamp(target, self.kinematics.arm_lower, self.kinematics.arm_upper)
        out_of_bounds |= bool((bounded != target).any())
        return Command(bounded, gripper, out_of_bounds, recorded=recorded)

    def _oriented_ik(self, state: EnvState, position: np.ndarray, yaw: float):
        """IK for the position with the tool as EE mode keeps it: as it is, or turned toward pointing down by at
        most TURN_PER_STEP (halved while no solution is found), so that from a pose far from it (the home of an
        arm that points its gripper forward) it turns over a few steps, each solve staying near the pose. `yaw`
        (the Δyaw row's turn, else 0) then turns that orientation about the vertical."""
        current = state.ee_rotation
        turned = pin.rpy.rpyToMatrix(0.0, 0.0, yaw) if yaw else None
        if self.top_down is None:
            rotation = current if turned is None else turned @ current
            return self.kinematics.solve_ik(
                state.q_arm, position, target_rotation=rotation, gripper=state.gripper, max_iterations=40
            )
        turn = pin.log3(nearest_top_down(self.top_down, current, self.closing_axis) @ current.T)
        angle = float(np.linalg.norm(turn))
        for share in (1.0, 0.5, 0.25):
            rotation = pin.exp3(turn * min(1.0, share * TURN_PER_STEP / max(angle, 1e-12))) @ current
            if turned is not None:
                rotation = turned @ rotation
            solution = self.kinematics.solve_ik(
                state.q_arm, position, target_rotation=rotation, gripper=state.gripper, max_iterations=40
            )
            if solution.success or angle < 1e-6:
                break
        return solution

    def _ee_target(
        self, arm: np.ndarray, state: EnvState, gripper: float | None, out_of_bounds: bool, recorded: np.ndarray
    ) -> Command:
        yaw = self.layout.delta_coeff * float(arm[3]) if self.layout.yaw else 0.0
        target = state.ee_position + self.layout.delta_coeff * arm[:3] if self.layout.delta else arm[:3]
        bounded = _clamp(target, self.workspace_min, self.workspace_max)
        out_of_bounds |= bool((bounded != target).any())
        solution = self._oriented_ik(state, bounded, yaw)
        step = np.max(np.abs(solution.q_arm - state.q_arm))
        if solution.success and step > self.max_joint_delta and self.top_down is not None:
            # a turn that costs more joint motion than a step allows goes the allowed part of the way
            return Command(
                state.q_arm + (solution.q_arm - state.q_arm) * (self.max_joint_delta / step),
                gripper,
                out_of_bounds,
                recorded=recorded,
            )
        if not solution.success or step > self.max_joint_delta:
            # Holding the orientation can be out of reach near the workspace edge,
            # or cost a large wrist roll on a 6-DoF arm: then only the position counts.
            # A turn the yaw row asked for is then not made, and that is flagged like a clamp.
            out_of_bounds |= yaw != 0.0
            solution = self.kinematics.solve_ik(state.q_arm, bounded, gripper=state.gripper, max_iterations=60)
        if not solution.success:
            return Command(
                None, gripper, out_of_bounds, f"IK found no joint target for EE {np.round(bounded, 3)}", recorded
            )
        return Command(solution.q_arm, gripper, out_of_bounds, recorded=recorded)
