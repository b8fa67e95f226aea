"""A real step's arm motion: what was commanded, how long the driver was given for it, and when it is done.

A step ends as it does in simulation: with the commanded motion done, then the observation. The driver is
given the motion's duration (a trajectory's time_from_start, or the time profile set at connect), and the
motion is done once every arm joint reads within the robot's settle tolerance of the target, at rest. One that is
not done `margin_s` after its duration is overdue: the arm is stopped and the episode ends with the reason.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from envfactory.backends.base import EpisodeAbort
from envfactory.backends.rosbridge.follow import MIN_MOTION
from envfactory.schema.driver import Settle

# An arm pressing into what holds it has slowed to a creep: at most this share of the fastest it moved for this
# command. An arm that still runs near its fastest is being driven slowly (a low speed scaling), not held.
PRESSING_SPEED_SHARE = 0.25


class MotionUnfinished(EpisodeAbort):
    """The arm moved but did not reach its target within the time its driver was given, plus the margin."""


@dataclass(frozen=True)
class Motion:
    start: np.ndarray  # where the arm was when the command went out
    target: np.ndarray
    sent_at: float  # time.monotonic()
    length_s: float  # how long the driver was given for it


class MotionWatch:
    def __init__(self, topic: str, settle: Settle):
        self.topic, self.settle = topic, settle
        self.motion: Motion | None = None
        self.done_at: float | None = None  # when the last motion was first read done
        self.gap = float("nan")  # how far from its target the arm was then, rad (the largest joint's)
        self.peak_speed = 0.0  # the fastest joint speed read since the command, rad/s

    def commanded(self, start: np.ndarray, target: np.ndarray, now: float, length_s: float) -> None:
        motion = Motion(np.asarray(start, float), np.asarray(target, float), now, length_s)
        self.motion, self.done_at, self.gap, self.peak_speed = motion, None, float("nan"), 0.0

    def done(self, q_arm: np.ndarray, qd_arm: np.ndarray, now: float) -> bool:
        """Whether the commanded motion is done (or nothing was commanded), on a fresh reading: every arm joint at
        rest, and at its target, or (once the driver's time is over, having moved) held back at most `held_back`
        from it. At the end of the margin, an arm held back that still creeps or trembles (pressing into what holds
        it) is done too once it has slowed to PRESSING_SPEED_SHARE of its fastest."""
        motion, settle = self.motion, self.settle
        if motion is None:
            return True
        speed = float(np.max(np.abs(qd_arm)))
        self.peak_speed = max(self.peak_speed, speed)
        gap = float(np.max(np.abs(q_arm - motion.target)))
        elapsed = now - motion.sent_at
        # held back: the arm followed (an arm that never moved has no driver carrying the command out)
        held = gap <= settle.held_back and float(np.max(np.abs(q_arm - motion.start))) >= MIN_MOTION
        pressing = (
            held and elapsed >= motion.length_s + settle.margin_s and speed <= PRESSING_SPEED_SHARE * self.peak_speed
        )
        if speed > settle.velocity and not pressing:
            return False
        if gap <= settle.tolerance or (held and elapsed >= motion.length_s):
            if self.done_at is None:
                self.done_at, self.gap = now, gap
            return True
        return False

    def check(self, q_arm: np.ndarray, qd_arm: np.ndarray, now: float) -> None:
        """MotionUnfinished once the motion is overdue and still not done."""
        motion = self.motion
        if motion is None or self.done(q_arm, qd_arm, now):
            return
        allowed = motion.length_s + self.settle.margin_s
        if now - motion.sent_at > allowed:
            off = np.abs(q_arm - motion.target)
            worst = int(np.argmax(off))
            raise MotionUnfinished(
                f"the arm did not finish the command on {self.topic} within {allowed:.2f} s (its driver was given "
                f"{motion.length_s:.2f} s, plus a margin of {self.settle.margin_s:.2f} s): joint {worst} is still "
                f"{off[worst]:.3f} rad from its target (settle tolerance {self.settle.tolerance:g} rad), the "
                f"fastest joint at {float(np.max(np.abs(qd_arm))):.3f} rad/s (settled below "
                f"{self.settle.velocity:g}). The driver's timing is not the one it was given, or the arm is blocked."
            )

    def motion_time(self) -> float:
        """Seconds from the last command to the reading that found it done; NaN if none was."""
        if self.motion is None or self.done_at is None:
            return float("nan")
        return self.done_at - self.motion.sent_at

    def clear(self) -> None:
        self.motion = self.done_at = None
        self.gap, self.peak_speed = float("nan"), 0.0


def drive_plan(
    start: np.ndarray, home: np.ndarray, speed: float, segment_s: float | None
) -> list[tuple[float, np.ndarray, float]]:
    """(send at s, target, duration s) of each command of a drive from `start` home at `speed` rad/s: one
    command when the command carries its duration (`segment_s` None); else, for a driver that moves each command
    over its own profile, segments of that profile, each at most `speed` times its length further than the
    last. At least a second in all."""
    total = max(1.0, float(np.max(np.abs(home - start))) / speed)
    if segment_s is None:
        return [(0.0, home, total)]
    count = max(1, math.ceil(total / segment_s))
    step = total / count
    return [(i * step, start + (home - start) * (i + 1) / count, step) for i in range(count)]
