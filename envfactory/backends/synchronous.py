"""A joint-synchronous move on every backend: how long it takes, and the profile along it. Both engines play it
substep by substep over this length, and the real path gives a driver this long (a trajectory's
time_from_start), so an arm never passes a joint's speed limit and every backend moves it over the same time."""

from __future__ import annotations

import numpy as np

from envfactory.geometry.timing_law import PEAK_OVER_MEAN_SPEED, quintic


def synchronous_length(start: np.ndarray, end: np.ndarray, duration: float, velocities: np.ndarray) -> float:
    """How long a joint-synchronous move takes: the commanded duration, or longer when the joint that
    travels furthest for its speed limit would pass that limit at the profile's peak."""
    if not len(start):
        return duration
    return max(duration, PEAK_OVER_MEAN_SPEED * float((np.abs(end - start) / velocities).max()))


class Profile:
    """A joint-synchronous straight line from `start` to `end`, beginning at `t0` and lasting `length` s: every
    joint covers the same fraction of its way at every instant, so the arm never leaves the line. `smooth`:
    the quintic timing law (an arm's point-to-point move); else constant speed (a gripper's finger drive).
    `start` and `end`: arrays of joint values, or plain floats for one joint (the gripper's)."""

    def __init__(self, start: np.ndarray, end: np.ndarray, t0: float, length: float, smooth: bool = True):
        self.start, self.end, self.t0, self.length, self.smooth = start, end, t0, max(length, 1e-9), smooth

    def at(self, time):
        """(position, velocity, acceleration) at `time`, a float or an array of times (then one row each)."""
        if isinstance(time, float):  # one instant, every kinematic cycle: plain numbers cost less than numpy's
            tau = min(max((time - self.t0) / self.length, 0.0), 1.0)
        else:
            tau = np.clip((np.asarray(time, float) - self.t0) / self.length, 0.0, 1.0)[..., None]
        if self.smooth:
            fraction = quintic(tau)
            rate = 30.0 * tau * tau * (1.0 - tau) ** 2 / self.length
            change = 60.0 * tau * (1.0 - tau) * (1.0 - 2.0 * tau) / (self.length * self.length)
        elif isinstance(tau, float):
            fraction, rate, change = tau, (1.0 / self.length if tau < 1.0 else 0.0), 0.0
        else:
            fraction, rate, change = tau, np.where(tau < 1.0, 1.0 / self.length, 0.0), np.zeros_like(tau)
        way = self.end - self.start
        return self.start + fraction * way, rate * way, change * way
