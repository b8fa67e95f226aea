"""Slide: get behind the puck on the puck→goal line, then strike it once hard enough to slide the rest of the
way (in EE mode a far puck in two legs: leave_short); wait while it slides, and strike again if it stops short
within reach.

On a surface of friction coefficient mu a puck struck to speed v slides v^2 / (2 mu g). The arm moves a step
along the quintic timing law (geometry/timing_law.py), whose peak speed is 15/8 of its mean: a puck the
striker meets before the peak rides with it up to the peak and leaves at that speed. So the strike is
L = v * action_speed / (15/8) long, and starts with the striker at most 0.4 L behind the puck (closer first,
in a step of its own that stops short of it).
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from envfactory.experts.push import PushExpert, PushParams
from envfactory.geometry.obstacles import SURFACE_FRICTION
from envfactory.geometry.timing_law import PEAK_OVER_MEAN_SPEED

GRAVITY = 9.81
# Faster than this, m/s, the puck is still sliding: the expert waits for it.
SLIDING = 0.01
# Strike only from within this of the push height, m: a striker higher than that passes over a low puck.
STRIKE_HEIGHT_TOLERANCE = 0.004
# The gap the closing-in step leaves between the striker and the puck, m.
CLOSE_GAP = 0.002


class SlideParams(PushParams):
    object: str = "puck"
    face: float = Field(gt=0, le=0.3)  # from the EE to the striking face of the gripper along the line, m
    # the table's, which the puck's multiplies
    surface_friction: float = Field(default=SURFACE_FRICTION[0], gt=0, le=2.0)
    # the struck puck's speed over the striker's mean: the timing law's peak, unless a robot's motors trail it
    speedup: float = Field(default=PEAK_OVER_MEAN_SPEED, gt=0, le=5.0)
    max_strike: float = Field(default=0.12, gt=0, le=0.5)  # the longest strike, m of EE travel in one step
    min_strike: float = Field(default=0.005, gt=0, le=0.5)  # the shortest, m
    # EE mode only: a puck farther than 1.5 times this from the goal is struck to stop this short of it, then
    # struck again from there, m (0: one strike). EE mode holds the striking face as it is, not square to the
    # line, and such a strike leaves up to ~10 deg off it: over a shorter last leg that misses by less. In joint
    # mode, and in EE mode with a yaw row, the face turns square and one strike is the more accurate.
    leave_short: float = Field(default=0.0, ge=0, le=1.0)


class SlideExpert(PushExpert):
    Params = SlideParams

    def __call__(self, observation):
        state = self.env.state
        puck = state.objects[self.params.object]
        tolerance = self.env.blueprint.spec.task.goal.tolerance
        arrived = np.linalg.norm(puck.position - self.env.goal_of(self.params.object)) < tolerance
        if arrived or np.linalg.norm(puck.linear_velocity[:2]) > SLIDING:
            # on its way, or there: rise clear of it (ready for a next strike, should it stop short or slide on)
            ee = state.ee_position
            clear = np.append(ee[:2], puck.position[2] + self.params.clearance)
            return self.motion.toward(clear, max_step=self.params.step)
        return super().__call__(observation)

    def drive(self, direction, offset: float, push_z: float, rotation, remaining: float):
        """Down to the push height where it stands, close in if the gap is too wide, then one strike."""
        p = self.params
        state = self.env.state
        ee = state.ee_position
        if ee[2] > push_z + STRIKE_HEIGHT_TOLERANCE:
            return self.motion.toward(np.append(ee[:2], push_z), rotation, max_step=p.step)
        # EE mode without a yaw row cannot square the face to the line: two legs miss by less
        split = self.motion.layout.ee and not self.motion.layout.yaw and remaining > 1.5 * p.leave_short
        leg = remaining - p.leave_short if split else remaining
        length = self.strike_length(leg)
        gap = -float((ee[:2] - state.objects[p.object].position[:2]) @ direction) - self._reach(direction) - p.face
        if gap > 0.4 * length + CLOSE_GAP:
            closer = gap - CLOSE_GAP
            return self.motion.toward(np.append(ee[:2] + direction * closer, push_z), rotation, max_step=closer)
        return self.motion.toward(np.append(ee[:2] + direction * length, push_z), rotation, max_step=length)

    def strike_length(self, remaining: float) -> float:
        p = self.params
        spec = self.env.blueprint.spec
        friction = spec.task.objects[p.object].friction * p.surface_friction
        speed = np.sqrt(2 * friction * GRAVITY * remaining)
        return float(np.clip(speed * spec.env.timing.action_speed / p.speedup, p.min_strike, p.max_strike))
