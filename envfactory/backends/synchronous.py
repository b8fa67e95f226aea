"""How long a joint-synchronous move takes, on every backend: MuJoCo plays it over this length, and the real
path gives a driver this long (a trajectory's time_from_start), so an arm never passes a joint's speed limit
and every backend moves it over the same time."""

from __future__ import annotations

import numpy as np

# The timing law along the line: a quintic in the elapsed fraction, so velocity and acceleration start and end
# at zero and the servos lag no step in either; its peak speed is this multiple of the mean.
PEAK_OVER_MEAN_SPEED = 1.875


def synchronous_length(start: np.ndarray, end: np.ndarray, duration: float, velocities: np.ndarray) -> float:
    """How long a joint-synchronous move takes: the commanded duration, or longer when the joint that
    travels furthest for its speed limit would pass that limit at the profile's peak."""
    if not len(start):
        return duration
    return max(duration, PEAK_OVER_MEAN_SPEED * float((np.abs(end - start) / velocities).max()))
