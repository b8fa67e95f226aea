"""The kinematic tree's forward kinematics compiled (its tables: joint_table.py): what every kernel poses the
shapes with. Numba compiles on first use and caches the result beside the module; the helpers a loop calls per
joint are inlined (a compiled call that passes a dozen arrays costs more, about 0.1 µs, than the arithmetic it
runs)."""

from __future__ import annotations

import numpy as np
from numba import njit

from envfactory.geometry.kernels.joint_table import FIXED, REVOLUTE


@njit(cache=True, inline="always")
def compose(up, local, out):
    """out = up * local for 3x4 rigid transforms [R | t] (written out: numba's @ would need BLAS)."""
    for i in range(3):
        for j in range(4):
            value = up[i, 0] * local[0, j] + up[i, 1] * local[1, j] + up[i, 2] * local[2, j]
            out[i, j] = value + up[i, 3] if j == 3 else value


@njit(cache=True, inline="always")
def placed_point(frame, x, y, z, i):
    """Coordinate i of the point (x, y, z) placed by the 3x4 rigid transform `frame`."""
    return frame[i, 0] * x + frame[i, 1] * y + frame[i, 2] * z + frame[i, 3]


@njit(cache=True, inline="always")
def joint_frame(joint, coordinates, parent, placement, kind, axis, coordinate, gain, frames, motion, local):
    """frames[joint]: the joint's base-frame placement, its parent's being in place (motion, local: 3x4 scratch)."""
    if kind[joint] == FIXED:
        compose(frames[parent[joint]], placement[joint], frames[joint])
        return
    value = gain[joint] * coordinates[coordinate[joint]]
    x, y, z = axis[joint, 0], axis[joint, 1], axis[joint, 2]
    motion[:, :] = 0.0
    if kind[joint] == REVOLUTE:  # Rodrigues' rotation about the unit axis
        c, s = np.cos(value), np.sin(value)
        t = 1.0 - c
        motion[0, 0], motion[0, 1], motion[0, 2] = c + t * x * x, t * x * y - s * z, t * x * z + s * y
        motion[1, 0], motion[1, 1], motion[1, 2] = t * x * y + s * z, c + t * y * y, t * y * z - s * x
        motion[2, 0], motion[2, 1], motion[2, 2] = t * x * z - s * y, t * y * z + s * x, c + t * z * z
    else:
        motion[0, 0] = motion[1, 1] = motion[2, 2] = 1.0
        motion[0, 3], motion[1, 3], motion[2, 3] = x * value, y * value, z * value
    compose(placement[joint], motion, local)
    compose(frames[parent[joint]], local, frames[joint])


@njit(cache=True, inline="always")
def root_frame(frames):
    """frames[0], the base's own placement: the identity."""
    frames[0, :, :] = 0.0
    for k in range(3):
        frames[0, k, k] = 1.0


@njit(cache=True, inline="always")
def joint_frames(coordinates, parent, placement, kind, axis, coordinate, gain, frames):
    """Base-frame placements of every joint at these coordinates, as 3x4 rows [R | t]."""
    root_frame(frames)
    motion = np.zeros((3, 4))
    local = np.empty((3, 4))
    for joint in range(1, parent.shape[0]):
        joint_frame(joint, coordinates, parent, placement, kind, axis, coordinate, gain, frames, motion, local)
