"""Push: get behind the cube on the cube→goal line, low, then push along it.

Closed loop: every step re-reads the cube, so a cube that turns or drifts
off the line sends the paddle back behind it.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from envfactory.experts.motion import Expert
from envfactory.experts.points import PARAMS, ExpertPoint, approach_point
from envfactory.terms.library import TermParams

# The push starts once the EE is within this above the push height, m; the compiler's reach checks allow the
# same slack (working_points).
PUSH_WITHIN = 0.02


class PushParams(TermParams):
    object: str = "cube"
    paddle: float = Field(
        default=0.02, gt=0, le=0.5
    )  # from the EE to the pushing face of the gripper, plus a margin, m
    height: float = Field(default=0.0, ge=-0.5, le=0.5)  # EE height above the cube centre while pushing, m
    clearance: float = Field(default=0.08, gt=0, le=1.0)  # EE height above the cube centre when moving around it, m
    step: float = Field(default=0.03, gt=0, le=0.5)  # EE travel per action, m
    lateral_tolerance: float = Field(default=0.012, gt=0, le=0.5)  # off-line distance that calls for a re-approach, m


class PushExpert(Expert):
    Params = PushParams

    @classmethod
    def working_points(cls, params, spec) -> list[ExpertPoint]:
        """Behind the object on the line from its spawn to the goal box's centre, the pushing face at half the
        object plus the paddle, at the push height; and above the object by the clearance, passing over it."""
        obj = spec.task.objects.get(params.object)
        if obj is None:
            return []
        spawn = np.asarray(obj.spawn.position, float)
        goal = np.mean(np.asarray(spec.task.goal.box, float), axis=0)
        direction = goal[:2] - spawn[:2]
        direction = direction / np.linalg.norm(direction) if np.linalg.norm(direction) > 1e-9 else np.array([1.0, 0])
        behind = spawn[:2] - direction * (obj.half_extents[0] + params.paddle)
        push = ExpertPoint(
            "push",
            f"{PARAMS}.height",
            np.array([[*behind, spawn[2] + params.height]]),
            params.height,
            (spec.gripper_assumed_at_reset,),
            PUSH_WITHIN,
            direction,
        )
        return [push, approach_point(params, obj)]

    def __call__(self, observation):
        env, p = self.env, self.params
        state = env.state
        cube = state.objects[p.object].position
        ee = state.ee_position
        to_goal = env.goal[:2] - cube[:2]
        remaining = np.linalg.norm(to_goal)
        if remaining < 1e-3:
            return self.motion.toward(ee)
        direction = to_goal / remaining
        rotation = self.motion.down_facing(direction)
        push_z = cube[2] + p.height
        clear_z = cube[2] + p.clearance
        offset = self._reach(direction) + p.paddle
        behind = cube[:2] - direction * offset
        relative = ee[:2] - cube[:2]
        along = float(relative @ direction)
        across = float(np.linalg.norm(relative - along * direction))
        low = ee[2] < push_z + PUSH_WITHIN
        if low and along < -offset + 0.015 and across < p.lateral_tolerance:
            # in contact range behind the object and on the line
            return self.drive(direction, offset, push_z, rotation, remaining)
        if low and along < -offset + 0.005:
            # still behind the object: slide sideways onto the line without touching it
            return self.motion.toward(np.append(behind, push_z), rotation, max_step=p.step)
        if np.linalg.norm(ee[:2] - behind) < 0.01:
            return self.motion.toward(np.append(behind, push_z), rotation, max_step=p.step)
        if ee[2] < clear_z - 0.01 and np.linalg.norm(ee[:2] - behind) > 0.02:
            # beside or ahead of the object: rise before moving over it
            return self.motion.toward(np.append(ee[:2], clear_z), rotation, max_step=p.step)
        return self.motion.toward(np.append(behind, clear_z), rotation, max_step=2 * p.step)

    def drive(self, direction, offset: float, push_z: float, rotation, remaining: float):
        """Push, aiming the object at the goal."""
        target = np.append(self.env.goal[:2] - direction * offset, push_z)
        return self.motion.toward(target, rotation, max_step=min(self.params.step, remaining + 0.005))

    def _reach(self, direction: np.ndarray) -> float:
        """How far the object reaches from its centre along `direction`: its radius if it is round; a box
        reaches further along a diagonal than across a face."""
        spec = self.env.blueprint.spec.task.objects[self.params.object]
        half = spec.half_extents[0]
        if spec.shape == "cylinder":
            return half
        yaw = self.env.state.objects[self.params.object].rpy[2]
        return half * (
            abs(np.cos(yaw) * direction[0] + np.sin(yaw) * direction[1])
            + abs(-np.sin(yaw) * direction[0] + np.cos(yaw) * direction[1])
        )
