"""Damped least-squares IK of the EE frame, compiled whole: every iteration's forward kinematics of the EE's chain,
its Jacobian, the orientation error and the damped step in one call.

EE mode solves IK at every step, a few times where the tool is turned toward pointing down, a few dozen
iterations in all. Each iteration's arithmetic is a few hundred flops; through Pinocchio and numpy it cost about
15 µs of call overhead, over half of an EE-mode step. The iteration is Kinematics.solve_ik's (its docstring
states the rules); Pinocchio stays the oracle the tests judge these frames, Jacobians and logarithms against.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from envfactory.geometry.kernels.damped_least_squares import damped_pseudo_inverse, damped_step
from envfactory.geometry.kernels.joint_table import FIXED, REVOLUTE
from envfactory.geometry.kernels.joints import compose, joint_frame, root_frame

# the largest change of a joint in one iteration (rad or m): a long step off a far target overshoots
STEP_LIMIT = 0.3
# an iteration that closes the position error by less than this has not closed in
PROGRESS = 1e-7
# iterations in a row without progress before the solve stops
STALL_LIMIT = 5
# the orientation is as near as the arm allows once the turn left changes by less than this in an iteration
TURN_SETTLED = 1e-6


@njit(cache=True, inline="always")
def rotation_log(m, out):
    """out: the rotation vector (axis times angle, angle in [0, π]) of the 3x3 rotation m."""
    cosine = min(max((m[0, 0] + m[1, 1] + m[2, 2] - 1.0) / 2.0, -1.0), 1.0)
    x, y, z = (m[2, 1] - m[1, 2]) / 2.0, (m[0, 2] - m[2, 0]) / 2.0, (m[1, 0] - m[0, 1]) / 2.0
    sine = math.sqrt(x * x + y * y + z * z)
    angle = math.atan2(sine, cosine)
    if cosine > 0.0 or sine > 1e-3:
        # angle / sine, by its series where the angle is so small that the division would lose digits
        factor = 1.0 + angle * angle / 6.0 if angle < 1e-4 else angle / sine
        out[0], out[1], out[2] = x * factor, y * factor, z * factor
        return
    # near a half turn the antisymmetric part vanishes; the symmetric part is (1 - cos) axis axisᵀ + cos I
    k = 0
    if m[1, 1] > m[k, k]:
        k = 1
    if m[2, 2] > m[k, k]:
        k = 2
    scale = math.sqrt((m[k, k] - cosine) * (1.0 - cosine))
    for i in range(3):
        out[i] = ((m[i, k] + m[k, i]) / 2.0 - (cosine if i == k else 0.0)) / scale
    if out[0] * x + out[1] * y + out[2] * z < 0.0:  # the antisymmetric part, however small, tells the sign
        for i in range(3):
            out[i] = -out[i]
    for i in range(3):
        out[i] *= angle


@njit(cache=True, inline="always")
def _norm(v):
    """The length of a 3-vector (products, not powers: the interpreter's x ** 2 calls pow, which may round the
    last bit otherwise than the compiled square, and the two forms must agree bit for bit)."""
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


@njit(cache=True, inline="always")
def ee_pose_and_jacobian(
    coordinates, chain, parent, placement, kind, axis, coordinate, gain, ee_placement, frames, ee, jacobian
):
    """ee: the EE frame's base-frame placement [R | t]; jacobian: its 6 x arm rows (linear, then angular
    velocity, in the base frame's axes, per unit speed of each arm coordinate: columns past the arm's are not
    filled)."""
    motion = np.empty((3, 4))
    local = np.empty((3, 4))
    root_frame(frames)
    for index in range(chain.shape[0]):
        joint_frame(chain[index], coordinates, parent, placement, kind, axis, coordinate, gain, frames, motion, local)
    compose(frames[chain[chain.shape[0] - 1]], ee_placement, ee)
    jacobian[:, :] = 0.0
    arm = jacobian.shape[1]
    for index in range(chain.shape[0]):
        joint = chain[index]
        column = coordinate[joint]
        if kind[joint] == FIXED or column >= arm:  # a fixed joint, or the gripper's coordinate: no IK variable
            continue
        frame, g = frames[joint], gain[joint]
        wx = frame[0, 0] * axis[joint, 0] + frame[0, 1] * axis[joint, 1] + frame[0, 2] * axis[joint, 2]
        wy = frame[1, 0] * axis[joint, 0] + frame[1, 1] * axis[joint, 1] + frame[1, 2] * axis[joint, 2]
        wz = frame[2, 0] * axis[joint, 0] + frame[2, 1] * axis[joint, 1] + frame[2, 2] * axis[joint, 2]
        if kind[joint] == REVOLUTE:
            rx, ry, rz = ee[0, 3] - frame[0, 3], ee[1, 3] - frame[1, 3], ee[2, 3] - frame[2, 3]
            jacobian[0, column] += g * (wy * rz - wz * ry)
            jacobian[1, column] += g * (wz * rx - wx * rz)
            jacobian[2, column] += g * (wx * ry - wy * rx)
            jacobian[3, column] += g * wx
            jacobian[4, column] += g * wy
            jacobian[5, column] += g * wz
        else:
            jacobian[0, column] += g * wx
            jacobian[1, column] += g * wy
            jacobian[2, column] += g * wz


@njit(cache=True, inline="always")
def _prioritised_step(jacobian, position_error, rotation_residual, damping):
    """A joint step that closes the position error, plus the orientation step projected onto the joint motions
    that leave the point where it is (damped least squares for both)."""
    arm = jacobian.shape[1]
    position_rows = np.ascontiguousarray(jacobian[:3])
    inverse = damped_pseudo_inverse(position_rows, damping)
    first = np.zeros(arm)
    for k in range(arm):
        for i in range(3):
            first[k] += inverse[k, i] * position_error[i]
    null = np.zeros((arm, arm))  # I - inverse · position rows
    for k in range(arm):
        for j in range(arm):
            total = 1.0 if k == j else 0.0
            for i in range(3):
                total -= inverse[k, i] * position_rows[i, j]
            null[k, j] = total
    rows = np.zeros((3, arm))  # rotation rows · null
    residual = np.empty(3)
    for r in range(3):
        moved = 0.0
        for j in range(arm):
            moved += jacobian[3 + r, j] * first[j]
            for k in range(arm):
                rows[r, j] += jacobian[3 + r, k] * null[k, j]
        residual[r] = rotation_residual[r] - moved
    second = damped_step(rows, residual, damping)
    step = first.copy()
    for k in range(arm):
        for j in range(arm):
            step[k] += null[k, j] * second[j]
    return step


@njit(cache=True)
def solve_ik(
    q_start,
    lower,
    upper,
    gripper,
    target_position,
    target_rotation,
    oriented,
    rotation_weight,
    max_iterations,
    tolerance,
    damping,
    chain,
    parent,
    placement,
    kind,
    axis,
    coordinate,
    gain,
    ee_placement,
    q_out,
):
    """Kinematics.solve_ik's iteration in the model's frame: q_out the joints found, the position error returned
    (the solve succeeded where it is below `tolerance`). `oriented`: whether target_rotation is asked for;
    `chain`: the EE's joints from the base (its frame hangs off the last, at ee_placement); the tree's tables are
    JointTable's, with the gripper's coordinate after the arm's."""
    arm = q_start.shape[0]
    coordinates = np.empty(coordinate.max() + 1)  # the arm's, then the gripper's if it has one
    if coordinates.shape[0] > arm:
        coordinates[arm:] = gripper
    frames = np.empty((parent.shape[0], 3, 4))
    ee = np.empty((3, 4))
    jacobian = np.empty((6, arm))
    position_error = np.empty(3)
    rotation_error = np.empty(3)
    turned = np.empty((3, 3))
    for k in range(arm):
        q_out[k] = min(max(q_start[k], lower[k]), upper[k])
    error, last_turn, closest, stalled = np.inf, np.inf, np.inf, 0
    for _ in range(max_iterations):
        coordinates[:arm] = q_out
        ee_pose_and_jacobian(
            coordinates, chain, parent, placement, kind, axis, coordinate, gain, ee_placement, frames, ee, jacobian
        )
        for i in range(3):
            position_error[i] = target_position[i] - ee[i, 3]
        error = _norm(position_error)
        if error < closest - PROGRESS:
            closest, stalled = error, 0
        else:
            stalled += 1
            if stalled >= STALL_LIMIT:
                break  # no longer closing in (out of reach, or held at a joint bound): more steps would not help
        if not oriented:
            if error < tolerance:
                return error
            step = damped_step(np.ascontiguousarray(jacobian[:3]), position_error, damping)
        else:
            for i in range(3):  # target · eeᵀ: the turn still to make, in the base frame
                for j in range(3):
                    turned[i, j] = 0.0
                    for k in range(3):
                        turned[i, j] += target_rotation[i, k] * ee[j, k]
            rotation_log(turned, rotation_error)
            turn = _norm(rotation_error)
            # on the point, and the orientation as near as the arm allows (an arm of fewer than six joints cannot
            # hold every orientation anywhere: its rotation error stops shrinking)
            if error < tolerance and (turn * rotation_weight < 10 * tolerance or abs(last_turn - turn) < TURN_SETTLED):
                return error
            last_turn = turn
            weighted = rotation_weight * rotation_error
            if arm < 6:
                # the position comes first; the orientation gets what the joints can do without moving the point
                step = _prioritised_step(jacobian, position_error, weighted, damping)
            else:
                rows = np.empty((6, arm))
                residual = np.empty(6)
                for i in range(3):
                    residual[i], residual[3 + i] = position_error[i], weighted[i]
                    for k in range(arm):
                        rows[i, k], rows[3 + i, k] = jacobian[i, k], rotation_weight * jacobian[3 + i, k]
                step = damped_step(rows, residual, damping)
        for k in range(arm):
            moved = q_out[k] + min(max(step[k], -STEP_LIMIT), STEP_LIMIT)
            q_out[k] = min(max(moved, lower[k]), upper[k])
    return error
