"""Goals: sampling in the goal box, reachable where the achieved goal is the EE."""

from __future__ import annotations

import numpy as np

from envfactory.geometry.kinematics import Kinematics
from envfactory.geometry.safety import SafetyCheck
from envfactory.schema.models import GoalSpec


class GoalSampler:
    """Uniform in the goal box, resampled until the arm can reach it safely (EE goals),
    or the static goal when random goals are off."""

    def __init__(
        self,
        goal: GoalSpec,
        kinematics: Kinematics,
        safety: SafetyCheck,
        home: np.ndarray,
        check_reach: bool,
        gripper: float = 0.0,
    ):
        self.tolerance = goal.tolerance
        self.resample_achieved = not goal.allow_achieved_at_reset
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

    def given(self, goal, where: str) -> np.ndarray:
        """A goal a caller chose (reset's options["goal"]), refused unless it is a finite point of the goal box:
        a goal the observation could not hold would be clipped, and one out of reach is no task."""
        try:
            point = np.asarray(goal, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"{where}: {goal!r} is not a point x, y, z (task frame, m)") from None
        if point.shape != (3,):
            raise ValueError(f"{where}: a goal is 3 numbers x, y, z (task frame, m), got shape {point.shape}")
        if not np.all(np.isfinite(point)):
            raise ValueError(f"{where}: {point.tolist()} is not finite")
        if np.any(point < self.low) or np.any(point > self.high):
            raise ValueError(
                f"{where}: {point.tolist()} lies outside the goal box {self.low.tolist()} .. {self.high.tolist()} "
                "(task.goal.box, task frame, m)"
            )
        return point

    def sample(self, rng: np.random.Generator, start: np.ndarray) -> tuple[np.ndarray, bool]:
        """A goal and whether sampling failed (every try unreachable, or already achieved from `start`, where
        the achieved point is at reset)."""
        if not self.random:
            return self.static.copy(), self.check_reach and not self.reachable(self.static)
        for _ in range(self.tries):
            goal = rng.uniform(self.low, self.high)
            if self.resample_achieved and np.linalg.norm(goal - start) < self.tolerance:
                continue
            if not self.check_reach or self.reachable(goal):
                return goal, False
        return goal, True
