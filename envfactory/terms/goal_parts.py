"""The goal vectors' layout: which points and orientations a goal places, in order.

A task's goal places one point (the EE or an object), and with `task.goal.also` further objects, each at
the goal plus its own offset: a stack's upper cube on top of the lower. With `task.goal.orientation` it also
turns objects: their orientations follow the points, as quaternions (x, y, z, w) in the task frame with w >= 0
(q and -q are the same orientation; the angle between two never depends on the sign). The desired and the
achieved goal hold the same parts in the same order, so HER relabels them as one vector, and every goal term
measures each part on its own: success needs every part within its tolerance, never a mean of them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from envfactory.geometry.vectors import length, lengths
from envfactory.schema.task import TURN_AXES, GoalSpec

POINT = 3  # coordinates per point part: a position, task frame
TURN = 4  # per orientation part: a quaternion x, y, z, w


@dataclass(frozen=True)
class GoalParts:
    names: tuple[str, ...]  # the point parts: "ee" or object names, the goal vectors' order
    offsets: np.ndarray  # (points, 3): each point part's goal from the goal, the first part's zero
    turned: tuple[str, ...] = ()  # the orientation parts' objects, after the points
    turns: tuple[np.ndarray, ...] = ()  # each orientation part's possible goals: (choices, 4) quaternions
    turn_tolerances: tuple[float, ...] = ()  # rad, each orientation part's

    @classmethod
    def of(cls, goal: GoalSpec) -> "GoalParts":
        turns = tuple(
            np.array([turn_quaternion(TURN_AXES[axis], np.radians(spec.angle)) for axis in spec.axes])
            for spec in goal.orientation.values()
        )
        tolerances = tuple(spec.tolerance for spec in goal.orientation.values())
        return cls(goal.parts, goal.part_offsets, tuple(goal.orientation), turns, tolerances)

    @property
    def points_size(self) -> int:
        return POINT * len(self.names)

    @property
    def size(self) -> int:
        return self.points_size + TURN * len(self.turned)

    def index(self, name: str) -> int:
        return self.names.index(name)

    def expand(self, goal: np.ndarray, rng: np.random.Generator | None = None) -> np.ndarray:
        """The desired goal: every point part's from the first part's goal, then an orientation drawn for each
        turned object (the first of its choices without a generator)."""
        points = (np.asarray(goal, float) + self.offsets).ravel()
        if not self.turned:
            return points
        drawn = [choices[rng.integers(len(choices)) if rng is not None else 0] for choices in self.turns]
        return np.concatenate([points, *drawn])

    def first(self, goals: np.ndarray) -> np.ndarray:
        """The first part's goal: the goal the goal box bounds."""
        return np.asarray(goals)[..., :POINT]

    def part(self, goals: np.ndarray, index: int) -> np.ndarray:
        return np.asarray(goals)[..., POINT * index : POINT * (index + 1)]

    def orientation(self, goals: np.ndarray, name: str) -> np.ndarray:
        start = self.points_size + TURN * self.turned.index(name)
        return np.asarray(goals)[..., start : start + TURN]

    def achieved(self, state) -> np.ndarray:
        points = [state.position_of(name) for name in self.names]
        turns = [rotation_quaternion(state.objects[name].rotation) for name in self.turned]
        return np.concatenate(points + turns)

    def distances(self, achieved: np.ndarray, desired: np.ndarray, part: int | None = None) -> np.ndarray:
        """Each point part's distance to its goal, or point part `part`'s alone: (..., points), over a batch of goal
        vectors or one."""
        size = self.points_size
        offset = np.asarray(achieved, float)[..., :size] - np.asarray(desired, float)[..., :size]
        if part is not None:
            offset = offset[..., POINT * part : POINT * (part + 1)]
        if offset.ndim == 1 and offset.size == POINT:  # a step's goal of one part: plain floats are faster
            return np.asarray([length(offset)])
        return lengths(offset.reshape(*offset.shape[:-1], -1, POINT))

    def angles(self, achieved: np.ndarray, desired: np.ndarray, part: int | None = None) -> np.ndarray:
        """Each orientation part's angle to its goal, or orientation part `part`'s alone, rad: (..., orientations)."""
        angles = quaternion_angles(
            np.asarray(achieved)[..., self.points_size :], np.asarray(desired)[..., self.points_size :]
        )
        return angles if part is None else angles[..., part : part + 1]

    def reached(self, achieved: np.ndarray, desired: np.ndarray, tolerance: float, part: int | None = None):
        """Every point part within `tolerance` of its goal, and every orientation part within its own; or point
        part `part` alone within `tolerance`. A stack is not half built when one cube is far and the other exact."""
        reached = (self.distances(achieved, desired, part) < tolerance).all(axis=-1)
        if self.turned and part is None:
            reached &= (self.angles(achieved, desired) < np.asarray(self.turn_tolerances)).all(axis=-1)
        return reached

    def stacked_bounds(self, low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The bounds of the desired goal from the box of the first part's goal."""
        return self._with_turns(self.expand(low)[: self.points_size], self.expand(high)[: self.points_size])

    def achieved_bounds(self, boxes) -> tuple[np.ndarray, np.ndarray]:
        """The bounds of the achieved goal: where each point part can be (PointBoxes)."""
        points = [boxes.of(name) for name in self.names]
        return self._with_turns(np.concatenate([b.low for b in points]), np.concatenate([b.high for b in points]))

    def _with_turns(self, low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        # a canonical quaternion: each of x, y, z in [-1, 1], w in [0, 1]
        turns = len(self.turned)
        return (
            np.concatenate([low, np.tile([-1.0, -1.0, -1.0, 0.0], turns)]),
            np.concatenate([high, np.ones(TURN * turns)]),
        )


def turn_quaternion(axis, angle: float) -> np.ndarray:
    """The quaternion (x, y, z, w) of a turn by `angle` rad about a unit axis, w >= 0."""
    return canonical(np.append(np.sin(angle / 2) * np.asarray(axis, float), np.cos(angle / 2)))


def rotation_quaternion(rotation: np.ndarray) -> np.ndarray:
    quaternion = pin.Quaternion(np.asarray(rotation, float))
    return canonical(np.array([quaternion.x, quaternion.y, quaternion.z, quaternion.w]))


def canonical(quaternion: np.ndarray) -> np.ndarray:
    """Of q and -q, the one with w >= 0: one vector per orientation, so the observation bounds hold w to [0, 1]."""
    return -quaternion if quaternion[3] < 0 else quaternion


def quaternion_angles(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """The angle between orientations, rad, (..., parts) from (..., 4 * parts): 2 acos |q1 . q2|, whatever the
    signs of the quaternions (renormalised: relabelled goals may have passed through float32)."""
    first = np.asarray(first, float).reshape(*np.shape(first)[:-1], -1, TURN)
    second = np.asarray(second, float).reshape(*np.shape(second)[:-1], -1, TURN)
    dot = np.abs((first * second).sum(axis=-1)) / (lengths(first) * lengths(second))
    return 2.0 * np.arccos(np.clip(dot, 0.0, 1.0))
