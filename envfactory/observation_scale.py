"""The opt-in scaled observation (`normalize_observations=True`).

Every column of the observation vector is mapped by its declared bounds, so
that [low, high] becomes [-1, 1]. The goals are mapped by the goal box instead,
and both of them by the same map: HER puts achieved goals where desired goals
go, and the policy must tell two goals 2 cm apart (a metre-wide box would make
that 0.04 of a unit). An achieved goal outside the goal box lands outside
[-1, 1], within its own declared box mapped the same way. Rewards and
terminations are computed on the goals in metres: the env maps them back.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces


class AffineScale:
    """x -> (x - centre) / half-range, per column; a column of zero range keeps its unit."""

    def __init__(self, low: np.ndarray, high: np.ndarray):
        low, high = np.asarray(low, float), np.asarray(high, float)
        self.centre = (low + high) / 2
        half = (high - low) / 2
        self.half = np.where(half > 0, half, 1.0)

    def to_policy(self, value: np.ndarray) -> np.ndarray:
        return ((np.asarray(value, float) - self.centre) / self.half).astype(np.float32)

    def to_metres(self, value: np.ndarray) -> np.ndarray:
        return np.asarray(value, float) * self.half + self.centre

    def box(self, low: np.ndarray, high: np.ndarray) -> spaces.Box:
        """The space a declared box becomes."""
        return spaces.Box(self.to_policy(low), self.to_policy(high), dtype=np.float32)
