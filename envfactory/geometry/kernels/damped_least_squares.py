"""Damped least squares on a Jacobian of a few rows, compiled.

Every IK iteration solves (J Jᵀ + λ² I) x = r for three to six rows. numpy's solve and inverse spend several
microseconds on a call whose arithmetic takes a fraction of one, and EE mode runs a few dozen iterations a
step; here the Gram matrix is factored by Cholesky (it is symmetric positive definite for any λ > 0) on plain
loops.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def _factor(rows, damping):
    """The lower Cholesky factor of rows rowsᵀ + damping² I."""
    m, n = rows.shape
    factor = np.zeros((m, m))
    for i in range(m):
        for j in range(i + 1):
            total = 0.0
            for k in range(n):
                total += rows[i, k] * rows[j, k]
            factor[i, j] = total
        factor[i, i] += damping * damping
    for j in range(m):
        total = factor[j, j]
        for k in range(j):
            total -= factor[j, k] * factor[j, k]
        factor[j, j] = np.sqrt(total)
        for i in range(j + 1, m):
            total = factor[i, j]
            for k in range(j):
                total -= factor[i, k] * factor[j, k]
            factor[i, j] = total / factor[j, j]
    return factor


@njit(cache=True, inline="always")
def _solve(factor, rhs, out):
    """out = (L Lᵀ)⁻¹ rhs for the Cholesky factor L."""
    m = factor.shape[0]
    for i in range(m):  # L y = rhs
        total = rhs[i]
        for k in range(i):
            total -= factor[i, k] * out[k]
        out[i] = total / factor[i, i]
    for i in range(m - 1, -1, -1):  # Lᵀ x = y
        total = out[i]
        for k in range(i + 1, m):
            total -= factor[k, i] * out[k]
        out[i] = total / factor[i, i]


@njit(cache=True)
def damped_step(rows, residual, damping):
    """The joint step rowsᵀ (rows rowsᵀ + damping² I)⁻¹ residual: the damped least-squares step that best closes
    `residual` through the Jacobian `rows`."""
    m, n = rows.shape
    x = np.empty(m)
    _solve(_factor(rows, damping), residual, x)
    step = np.zeros(n)
    for k in range(n):
        for i in range(m):
            step[k] += rows[i, k] * x[i]
    return step


@njit(cache=True)
def damped_pseudo_inverse(rows, damping):
    """rowsᵀ (rows rowsᵀ + damping² I)⁻¹, (columns x rows)."""
    m, n = rows.shape
    factor = _factor(rows, damping)
    unit, column = np.zeros(m), np.empty(m)
    inverse = np.zeros((n, m))
    for j in range(m):
        unit[:] = 0.0
        unit[j] = 1.0
        _solve(factor, unit, column)
        for k in range(n):
            for i in range(m):
                inverse[k, j] += rows[i, k] * column[i]
    return inverse
