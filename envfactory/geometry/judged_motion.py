"""What the safety check judges and what it answers: a straight joint-space Motion of the arm (and the gripper's
range during it), the Anchor of lower bounds on each pair's clearance at one of its poses, the pairs two anchors
leave unproven, and the Verdict."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Verdict:
    accepted: bool
    reason: str = ""


ACCEPTED = Verdict(True)


@dataclass
class Anchor:
    """One arm pose of a motion, with a lower bound on each pair's clearance there over the whole
    range the gripper sweeps in the motion. Bounds tighten in levels: capsules (0), coal at the
    gripper's middle value less the gripper's half-travel (1), coal across the gripper's range (2)."""

    fraction: float
    q_arm: np.ndarray
    bound: np.ndarray
    level: np.ndarray  # per pair


@dataclass(frozen=True)
class Motion:
    """A straight joint-space motion of the arm, and the gripper's range during it."""

    q_from: np.ndarray
    q_to: np.ndarray
    gripper_from: float
    gripper_to: float
    travel: np.ndarray  # per pair: how far the arm's motion can close it, end to end
    reserve: np.ndarray  # per pair: how far the gripper's motion can close it from its middle value
    threshold: np.ndarray  # per pair: the clearance it must keep
    gripper_moves: bool = False
    samples: tuple[int, int] = (0, -1)  # the fingers' table samples bracketing the gripper's range (bracket())
    way: np.ndarray = field(init=False)  # q_to - q_from: asked for at every piece

    @property
    def gripper_middle(self) -> float:
        return (self.gripper_from + self.gripper_to) / 2

    def __post_init__(self) -> None:
        object.__setattr__(self, "way", self.q_to - self.q_from)

    def arm_at(self, fraction: float) -> np.ndarray:
        return self.q_from + fraction * self.way


def weak_pairs(a: Anchor, b: Anchor, motion: Motion, length: float, pairs: np.ndarray | None) -> np.ndarray:
    """The pairs (of these, or of all) whose clearance between two anchors is not proven above their threshold."""
    if pairs is None:
        return (a.bound + b.bound - motion.travel * length < 2 * motion.threshold).nonzero()[0]
    proven = a.bound[pairs] + b.bound[pairs] - motion.travel[pairs] * length >= 2 * motion.threshold[pairs]
    return pairs[~proven]
