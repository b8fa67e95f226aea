"""The timing law every arm motion follows along its joint-space line: a quintic in the elapsed fraction, so
velocity and acceleration start and end at zero and the servos lag no step in either. The backends play it
(backends/synchronous.py); an expert that needs the arm's speed along a step reckons with it."""

from __future__ import annotations

# its peak speed, half way, over its mean
PEAK_OVER_MEAN_SPEED = 1.875


def quintic(tau):
    """The share of the way covered at each elapsed fraction."""
    return tau**3 * (10.0 - 15.0 * tau + 6.0 * tau * tau)
