"""The opt-in normalised spaces: `normalize_actions=True` and `normalize_observations=True`.

Actions. Every row of the action box becomes [-1, 1]. A delta row keeps zero as
"no motion": [-1, 0] maps onto [low, 0] and [0, 1] onto [0, high], so an
asymmetric action row (the VX300S shoulder, -1.85 … +1.26) is scaled by a
different factor on each side. An absolute row (a joint or EE target, the PnP
gripper command) maps [-1, 1] affinely onto [low, high].

Observations. Every column of the observation vector is mapped affinely by its
declared bounds, so that [low, high] becomes [-1, 1]. The goals are mapped by
the goal box instead, and both of them by the same map: HER puts achieved goals
where desired goals go, and the policy must tell two goals 2 cm apart (a
metre-wide box would make that 0.04 of a unit). An achieved goal outside the
goal box lands outside [-1, 1], within its own declared box mapped the same
way. Rewards and terminations are computed on the goals in metres: the env
maps them back.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces


class AffineScale:
    """x -> (x - centre) / half-range, per column, so [low, high] becomes [-1, 1]; a column of zero
    range keeps its unit."""

    def __init__(self, low: np.ndarray, high: np.ndarray):
        low, high = np.asarray(low, float), np.asarray(high, float)
        self.centre = (low + high) / 2
        half = (high - low) / 2
        self.half = np.where(half > 0, half, 1.0)

    def to_unit(self, value: np.ndarray) -> np.ndarray:
        return (np.asarray(value, float) - self.centre) / self.half

    def from_unit(self, value: np.ndarray) -> np.ndarray:
        return np.asarray(value, float) * self.half + self.centre

    def box(self, low: np.ndarray, high: np.ndarray) -> spaces.Box:
        """The space a declared box becomes."""
        return spaces.Box(self.to_unit(low).astype(np.float32), self.to_unit(high).astype(np.float32), dtype=np.float32)


class ActionScale:
    def __init__(self, low: np.ndarray, high: np.ndarray, centred: np.ndarray):
        self.low, self.high = np.asarray(low, float), np.asarray(high, float)
        self.centred = np.asarray(centred, bool)  # rows where 0 means no motion
        self.affine = AffineScale(self.low, self.high)  # the absolute rows

    def to_seed(self, action: np.ndarray) -> np.ndarray:
        """A policy action in [-1, 1] in the spec's units."""
        action = np.asarray(action, float)
        centred = np.where(action >= 0, action * self.high, -action * self.low)
        return np.where(self.centred, centred, self.affine.from_unit(action))

    def to_policy(self, action: np.ndarray) -> np.ndarray:
        """An action in the spec's units (within its box) as the policy's [-1, 1]."""
        action = np.asarray(action, float)
        side = np.where(action >= 0, self.high, -self.low)  # a centred row has low < 0 < high
        centred = np.divide(action, side, out=np.zeros_like(action), where=self.centred)
        return np.clip(np.where(self.centred, centred, self.affine.to_unit(action)), -1.0, 1.0)

    def mapping(self, row: int) -> str:
        """How one row maps, for `describe`."""
        low, high = self.low[row], self.high[row]
        if self.centred[row]:
            return f"-1→{low:+.3g}, 0→0, +1→{high:+.3g}"
        return f"-1→{low:+.3g}, +1→{high:+.3g}"
