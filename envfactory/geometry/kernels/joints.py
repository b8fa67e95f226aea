"""The kinematic tree as flat arrays, and its forward kinematics compiled: what every kernel poses the shapes
with. Numba compiles on first use and caches the result beside the module; the helpers a loop calls per joint are
inlined (a compiled call that passes a dozen arrays costs more, about 0.1 µs, than the arithmetic it runs)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from numba import njit

FIXED, REVOLUTE, PRISMATIC = 0, 1, 2
NO_BOUND = -np.inf  # capsules that overlap say only that the shapes may touch


class JointTable:
    """The kinematic tree as flat arrays: per joint, its parent, its placement in the parent (the motion
    of an undriven joint at its neutral value folded in), its kind, axis, and which coordinate drives it
    with what gain."""

    def __init__(self, model, drivers: dict[int, tuple[int, float]]):
        data = model.createData()
        pin.forwardKinematics(model, data, pin.neutral(model))
        count = model.njoints
        self.parent = np.array(model.parents, dtype=np.int64)
        self.placement = np.zeros((count, 3, 4))
        self.kind = np.zeros(count, dtype=np.int64)
        self.axis = np.zeros((count, 3))
        self.coordinate = np.zeros(count, dtype=np.int64)
        self.gain = np.zeros(count)
        for joint in range(1, count):
            if joint not in drivers:
                self.placement[joint] = data.liMi[joint].homogeneous[:3]
                continue
            self.placement[joint] = model.jointPlacements[joint].homogeneous[:3]
            self.kind[joint], self.axis[joint] = _motion_of(model, joint)
            self.coordinate[joint], self.gain[joint] = drivers[joint]


def _motion_of(model, joint: int) -> tuple[int, np.ndarray]:
    """The kind and unit axis of a driven joint, read off its motion at a unit value."""
    joint_model = model.joints[joint]
    if joint_model.nq != 1:
        raise ValueError(
            f"joint {model.names[joint]!r} ({joint_model.shortname()}) is driven but is not "
            f"a one-coordinate revolute or prismatic joint"
        )
    q = pin.neutral(model)
    q[joint_model.idx_q] = 1.0
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    motion = pin.log6(model.jointPlacements[joint].actInv(data.liMi[joint]))  # a screw through the joint origin
    angular, linear = np.linalg.norm(motion.angular), np.linalg.norm(motion.linear)
    if angular > 1e-9 and linear < 1e-9:
        return REVOLUTE, motion.angular / angular
    if angular < 1e-9 and linear > 1e-9:
        return PRISMATIC, motion.linear / linear
    raise ValueError(
        f"joint {model.names[joint]!r} ({joint_model.shortname()}) is neither a plain revolute "
        f"nor a plain prismatic joint"
    )


@njit(cache=True, inline="always")
def _compose(up, local, out):
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
def joint_frames(coordinates, parent, placement, kind, axis, coordinate, gain, frames):
    """Base-frame placements of every joint at these coordinates, as 3x4 rows [R | t]."""
    frames[0, :, :] = 0.0
    for k in range(3):
        frames[0, k, k] = 1.0
    motion = np.zeros((3, 4))
    local = np.empty((3, 4))
    for joint in range(1, parent.shape[0]):
        if kind[joint] == FIXED:
            _compose(frames[parent[joint]], placement[joint], frames[joint])
            continue
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
        _compose(placement[joint], motion, local)
        _compose(frames[parent[joint]], local, frames[joint])
