"""Reach: steer the EE straight at the goal."""

from __future__ import annotations

from envfactory.experts.motion import Expert
from envfactory.terms.library import NoParams


class ReachExpert(Expert):
    Params = NoParams

    def __call__(self, observation):
        # the whole way in one step when the action box allows it
        gripper = self.motion.gripper.open if self.motion.gripper is not None else None
        return self.motion.toward(self.env.goal, gripper=gripper, max_step=10.0)
