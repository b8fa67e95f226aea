"""Stack: pick and place each part of the goal in turn, bottom first, letting go of each, the last one too:
the stack it leaves stands on its own.

One pick-and-place expert per part does the carrying; this one only orders them. A part counts as placed when
its cube rests within a fraction of the tolerance of its goal, so the next cube lands square on it; a placed
cube that is knocked off its goal is placed again before anything goes on top of it.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from envfactory.experts.motion import Expert
from envfactory.experts.pnp import CarryParams, PickPlaceExpert, PickPlaceParams

SETTLED = 0.01  # m/s: a cube slower than this rests where it is


class StackParams(CarryParams):
    # a part is placed within this fraction of the goal's tolerance: the next cube goes on its goal, not on the
    # cube below, so the cube below must be nearly exact
    placed_within: float = Field(default=0.3, gt=0, le=1.0)


class StackExpert(Expert):
    Params = StackParams

    @classmethod
    def _carriers(cls, params, spec) -> list[PickPlaceParams]:
        carry = params.model_dump(exclude={"placed_within"})
        return [PickPlaceParams(object=name, **carry) for name in spec.task.goal.parts]

    @classmethod
    def working_points(cls, params, spec) -> list:
        return [
            point for carrier in cls._carriers(params, spec) for point in PickPlaceExpert.working_points(carrier, spec)
        ]

    @classmethod
    def check(cls, params, spec) -> list[tuple[str, str]]:
        if spec.task.goal.parts[0] == "ee":
            return [("policy", "stack places objects: the goal's parts must be objects")]
        return PickPlaceExpert.check(cls._carriers(params, spec)[0], spec)

    def __init__(self, env, params):
        self.carriers = [PickPlaceExpert(env, carrier) for carrier in self._carriers(params, env.blueprint.spec)]
        super().__init__(env, params)

    def reset(self) -> None:
        self.index = 0
        self.releasing = False
        for carrier in self.carriers:
            carrier.reset()

    def _placed(self, index: int) -> bool:
        env = self.env
        name = self.carriers[index].params.object
        cube = env.state.objects[name]
        tolerance = env.blueprint.spec.task.goal.tolerance
        near = np.linalg.norm(cube.position - env.goal_of(name)) < self.params.placed_within * tolerance
        return near and np.linalg.norm(cube.linear_velocity) < SETTLED

    def __call__(self, observation):
        # a cube placed before that has left its goal since goes back first
        for below in range(self.index if not self.releasing else 0):
            if not self._placed(below):
                self.index, self.releasing = below, False
                self.carriers[below].reset()
                break
        if self.index == len(self.carriers):  # every cube placed and let go: the stack stands on its own
            return self._stand_clear()
        carrier = self.carriers[self.index]
        if not self.releasing and carrier.phase == "place" and self._placed(self.index):
            self.releasing = True
        if self.releasing:
            return self._release(carrier)
        return carrier(observation)

    def _release(self, carrier: PickPlaceExpert):
        """Open, and rise straight up clear of the placed cube; then the next part."""
        state, motion, p = self.env.state, self.motion, self.params
        cube = state.objects[carrier.params.object].position
        ee = state.ee_position
        if motion.gripper.closure(state.gripper) < 0.1 and ee[2] > cube[2] + p.clearance - 0.02:
            self.releasing = False
            self.index += 1
            if self.index == len(self.carriers):
                return self._stand_clear()
            self.carriers[self.index].reset()
            return self.carriers[self.index](None)
        return motion.toward(np.append(ee[:2], cube[2] + p.clearance), gripper=motion.gripper.open, max_step=p.step)

    def _stand_clear(self):
        return self.motion.toward(self.env.state.ee_position, gripper=self.motion.gripper.open)
