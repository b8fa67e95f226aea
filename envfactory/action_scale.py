"""The opt-in normalised action space (`normalize_actions=True`): every row in [-1, 1].

A delta row keeps zero as "no motion": [-1, 0] maps onto [low, 0] and [0, 1]
onto [0, high], so an asymmetric seed row (the VX300S shoulder, -1.85 … +1.26)
is scaled by a different factor on each side. An absolute row (a joint or EE
target, the PnP gripper command) maps [-1, 1] affinely onto [low, high].
"""

from __future__ import annotations

import numpy as np


class ActionScale:
    def __init__(self, low: np.ndarray, high: np.ndarray, centred: np.ndarray):
        self.low, self.high = np.asarray(low, float), np.asarray(high, float)
        self.centred = np.asarray(centred, bool)  # rows where 0 means no motion

    def to_seed(self, action: np.ndarray) -> np.ndarray:
        """A policy action in [-1, 1] as the seed's units."""
        action = np.asarray(action, float)
        centred = np.where(action >= 0, action * self.high, -action * self.low)
        affine = self.low + (action + 1.0) * (self.high - self.low) / 2.0
        return np.where(self.centred, centred, affine)

    def to_policy(self, action: np.ndarray) -> np.ndarray:
        """An action in the seed's units (within its box) as the policy's [-1, 1]."""
        action = np.asarray(action, float)
        side = np.where(action >= 0, self.high, -self.low)  # a centred row has low < 0 < high
        centred = np.divide(action, side, out=np.zeros_like(action), where=self.centred)
        affine = 2.0 * (action - self.low) / (self.high - self.low) - 1.0
        return np.clip(np.where(self.centred, centred, affine), -1.0, 1.0)

    def mapping(self, row: int) -> str:
        """How one row maps, for `describe`."""
        low, high = self.low[row], self.high[row]
        if self.centred[row]:
            return f"-1→{low:+.3g}, 0→0, +1→{high:+.3g}"
        return f"-1→{low:+.3g}, +1→{high:+.3g}"
