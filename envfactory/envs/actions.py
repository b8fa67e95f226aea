"""Turns a policy action into a joint target, saying what it had to change.

Out-of-bounds values are clipped and flagged (the joint-limits penalty);
actions that cannot be executed safely are rejected (the none-exe penalty)
and never reach the backend.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from envfactory.compiler import ActionLayout
from envfactory.geometry.kinematics import Kinematics
from envfactory.schema.models import Workspace
from envfactory.state import EnvState


@dataclass(frozen=True)
class Command:
    q_arm: np.ndarray | None  # None: the action is rejected, the arm holds
    gripper: float | None
    out_of_bounds: bool
    rejection: str = ""


class ActionAdapter:
    def __init__(self, layout: ActionLayout, kinematics: Kinematics, workspace: Workspace, max_joint_delta: float):
        self.layout = layout
        self.max_joint_delta = max_joint_delta
        self.kinematics = kinematics
        self.low, self.high = layout.low, layout.high
        self.scale = layout.scale if layout.normalize else None
        self.workspace_min = np.asarray(workspace.min, float)
        self.workspace_max = np.asarray(workspace.max, float)
        self.arm_size = layout.size - (1 if layout.gripper_in_action else 0)

    def clip(self, action: np.ndarray) -> tuple[np.ndarray, bool]:
        clipped = np.clip(action, self.low, self.high)
        return clipped, bool(np.any(clipped != action))

    def to_policy(self, action: np.ndarray) -> np.ndarray:
        """An action in the seed's units as the policy's action space has it."""
        action = np.clip(action, self.low, self.high)
        return (self.scale.to_policy(action) if self.scale is not None else action).astype(np.float32)

    def hold_action(self, state: EnvState) -> np.ndarray:
        """The action that keeps the robot where it is: the previous action a reset reports."""
        if self.layout.delta:
            arm = np.zeros(self.arm_size)
        else:
            arm = state.ee_position if self.layout.ee else state.q_arm
        return self.to_policy(np.append(arm, state.gripper) if self.layout.gripper_in_action else arm)

    def translate(self, action: np.ndarray, state: EnvState) -> Command:
        action = np.asarray(action, dtype=float).reshape(-1)
        if action.shape != (self.layout.size,):
            raise ValueError(f"action has shape {action.shape}, expected ({self.layout.size},)")
        if not np.all(np.isfinite(action)):
            return Command(None, None, False, "non-finite action")
        if self.scale is not None:
            normalised = np.clip(action, -1.0, 1.0)
            action, out_of_bounds = self.scale.to_seed(normalised), bool(np.any(normalised != action))
        else:
            action, out_of_bounds = self.clip(action)
        gripper = float(action[-1]) if self.layout.gripper_in_action else None
        arm = action[: self.arm_size]
        if self.layout.ee:
            return self._ee_target(arm, state, gripper, out_of_bounds)
        target = state.q_arm + self.layout.delta_coeff * arm if self.layout.delta else arm
        bounded = np.clip(target, self.kinematics.arm_lower, self.kinematics.arm_upper)
        out_of_bounds |= bool(np.any(bounded != target))
        return Command(bounded, gripper, out_of_bounds)

    def _ee_target(self, arm: np.ndarray, state: EnvState, gripper: float | None, out_of_bounds: bool) -> Command:
        target = state.ee_position + self.layout.delta_coeff * arm if self.layout.delta else arm
        bounded = np.clip(target, self.workspace_min, self.workspace_max)
        out_of_bounds |= bool(np.any(bounded != target))
        # keep the wrist's current orientation so a position step does not spin it
        solution = self.kinematics.solve_ik(
            state.q_arm, bounded, target_rotation=state.ee_rotation, gripper=state.gripper, max_iterations=40
        )
        if not solution.success or np.max(np.abs(solution.q_arm - state.q_arm)) > self.max_joint_delta:
            # Holding the orientation can be out of reach near the workspace edge,
            # or cost a large wrist roll on a 6-DoF arm: then only the position counts.
            solution = self.kinematics.solve_ik(state.q_arm, bounded, gripper=state.gripper, max_iterations=60)
        if not solution.success:
            return Command(None, gripper, out_of_bounds, f"IK found no joint target for EE {np.round(bounded, 3)}")
        return Command(solution.q_arm, gripper, out_of_bounds)
