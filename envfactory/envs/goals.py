"""Goals: sampling in the goal box, and the lift-then-place curriculum."""

from __future__ import annotations

import numpy as np

from envfactory.geometry.kinematics import Kinematics
from envfactory.geometry.safety import SafetyCheck
from envfactory.schema.models import GoalSpec
from envfactory.terms.rewards import STAGE_KEYS


class GoalSampler:
    """Uniform in the goal box, resampled until the arm can reach it safely (EE goals),
    or the static goal when random goals are off."""

    def __init__(self, goal: GoalSpec, kinematics: Kinematics, safety: SafetyCheck, home: np.ndarray,
                 check_reach: bool, gripper: float = 0.0):
        self.low = np.asarray(goal.box[0], float)
        self.high = np.asarray(goal.box[1], float)
        self.random = goal.random
        self.static = np.asarray(goal.static_goal, float)
        self.tries = goal.sampling_tries
        self.kinematics = kinematics
        self.safety = safety
        self.home = np.asarray(home, float)
        self.check_reach = check_reach
        self.gripper = gripper  # the gripper as a reset leaves it: its fingers must clear too

    def reachable(self, goal: np.ndarray) -> bool:
        solution = self.kinematics.solve_ik(self.home, goal, gripper=self.gripper)
        return solution.success and self.safety.pose_is_clear(solution.q_arm, self.gripper)

    def sample(self, rng: np.random.Generator) -> tuple[np.ndarray, bool]:
        """A goal and whether sampling failed (every try unreachable)."""
        if not self.random:
            return self.static.copy(), self.check_reach and not self.reachable(self.static)
        for _ in range(self.tries):
            goal = rng.uniform(self.low, self.high)
            if not self.check_reach or self.reachable(goal):
                return goal, False
        return goal, True


class LiftCurriculum:
    """multi_goal: the current goal is the spawn point raised by the lift height until the
    object gets there within tolerance, then the desired goal."""

    def __init__(self, enabled: bool, height: float, tolerance: float):
        self.enabled = enabled
        self.offset = np.array([0.0, 0.0, height])
        self.tolerance = tolerance
        self.goal = np.zeros(3)
        self.active = False

    def reset(self, spawn_position: np.ndarray) -> None:
        self.goal = np.asarray(spawn_position, float) + self.offset
        self.active = self.enabled

    def update(self, achieved: np.ndarray) -> None:
        if self.active and np.linalg.norm(achieved - self.goal) < self.tolerance:
            self.active = False

    def current(self, desired: np.ndarray) -> np.ndarray:
        return self.goal if self.active else desired

    def info(self) -> dict:
        return dict(zip(STAGE_KEYS, (float(self.active), self.goal.copy()), strict=True))
