"""The kinematic tree as the flat arrays every kernel poses the shapes with (joints.py runs it). Apart from the
kernels so that an env served by the ahead-of-time kernels (native.py) builds its tables without numba."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

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
