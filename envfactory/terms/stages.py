"""Task stages: a goal the episode pursues before the desired one.

A task declares its stage in the goal spec (today the pick-and-place lift stage,
`task.goal.lift`); the compiler turns it into a stage factory in the blueprint, and
the env asks its stage for the current goal and records the stage in `info` at
every step without knowing which stage it is. The recorded goal does not derive
from the desired goal, so rewards relabelled by HER stay exact.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Callable, Protocol

import numpy as np

from envfactory.geometry.vectors import length
from envfactory.schema.task import GoalSpec

# recorded at every step, also without a stage (then never active)
STAGE_KEYS = ("intermediate_active", "intermediate_goal")


class Stage(Protocol):
    def reset(self, spawn: dict[str, tuple[np.ndarray, np.ndarray]]) -> None:
        """A new episode, with the objects where they were spawned (name -> (position, orientation))."""

    def update(self, achieved: np.ndarray) -> None:
        """The achieved goal after a step."""

    def current(self, desired: np.ndarray) -> np.ndarray:
        """The goal the episode pursues now."""

    def info(self, desired: np.ndarray) -> dict:
        """The STAGE_KEYS entries of this step's info."""


class NoStage:
    """The desired goal from the first step."""

    def reset(self, spawn) -> None:
        pass

    def update(self, achieved: np.ndarray) -> None:
        pass

    def current(self, desired: np.ndarray) -> np.ndarray:
        return desired

    def info(self, desired: np.ndarray) -> dict:
        return dict(zip(STAGE_KEYS, (0.0, desired.copy()), strict=True))


@dataclass
class LiftStage:
    """multi_goal: the current goal is the object's spawn point raised by the lift height until the object
    gets there within tolerance, then the desired goal (a disabled stage is never active)."""

    obj: str
    enabled: bool
    height: float
    tolerance: float

    def __post_init__(self):
        self.goal = np.zeros(3)
        self.active = False

    def reset(self, spawn) -> None:
        self.goal = np.asarray(spawn[self.obj][0], float) + [0.0, 0.0, self.height]
        self.active = self.enabled

    def update(self, achieved: np.ndarray) -> None:
        if self.active and length(achieved - self.goal) < self.tolerance:
            self.active = False

    def current(self, desired: np.ndarray) -> np.ndarray:
        return self.goal if self.active else desired

    def info(self, desired: np.ndarray) -> dict:
        return dict(zip(STAGE_KEYS, (float(self.active), self.goal.copy()), strict=True))


def stage_factory(goal: GoalSpec) -> Callable[[], Stage]:
    """What builds a fresh stage for each env (a stage keeps its episode's state); picklable, as blueprints
    travel to other processes."""
    lift = goal.lift
    if lift is None:
        return NoStage
    return functools.partial(LiftStage, goal.achieved.partition(".")[0], lift.enabled, lift.height, goal.tolerance)
