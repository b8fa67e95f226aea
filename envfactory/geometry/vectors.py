"""Euclidean lengths of the small vectors a step measures, without numpy.linalg.norm's per-call overhead.

A step measures about ten 3-vectors (goal distances, grasp tests, the stage goal, the observation's goal
terms); numpy's norm spends more on handling its arguments than on the arithmetic, about a microsecond each.
"""

from __future__ import annotations

import math

import numpy as np


def length(vector: np.ndarray) -> float:
    """The length of one vector (as plain floats: for three numbers, a tenth of any numpy call's cost)."""
    return math.hypot(*np.asarray(vector, dtype=float).ravel().tolist())


def lengths(vectors: np.ndarray) -> np.ndarray:
    """The length of each vector along the last axis (a batch of goals, or one)."""
    vectors = np.asarray(vectors, dtype=float)
    if vectors.ndim == 1:  # one vector (a step's): a 0-d result, as the batch arithmetic would give
        return np.asarray(length(vectors))
    return np.sqrt((vectors * vectors).sum(axis=-1))
