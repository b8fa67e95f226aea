"""Goal sampling: uniform in the goal box, resampled until the arm can reach it safely."""

from __future__ import annotations

import numpy as np

from envfactory.kinematics import Kinematics
from envfactory.safety import SafetyCheck
from envfactory.spec.schema import GoalSpec


class GoalSampler:
    def __init__(self, goal: GoalSpec, kinematics: Kinematics, safety: SafetyCheck, home: np.ndarray,
                 check_reach: bool):
        self.low = np.asarray(goal.box[0], float)
        self.high = np.asarray(goal.box[1], float)
        self.tries = goal.sampling_tries
        self.kinematics = kinematics
        self.safety = safety
        self.home = np.asarray(home, float)
        self.check_reach = check_reach

    def reachable(self, goal: np.ndarray) -> bool:
        solution = self.kinematics.solve_ik(self.home, goal)
        return solution.success and self.safety.pose_is_clear(solution.q_arm)

    def sample(self, rng: np.random.Generator) -> tuple[np.ndarray, bool]:
        """A goal and whether sampling failed (every try unreachable)."""
        goal = rng.uniform(self.low, self.high)
        if not self.check_reach:
            return goal, False
        for _ in range(self.tries):
            if self.reachable(goal):
                return goal, False
            goal = rng.uniform(self.low, self.high)
        return goal, True
