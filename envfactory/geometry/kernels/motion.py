"""The proof of a whole motion, compiled: each pair's travel and reserve along the straight joint-space line, the
bounds at its ends, and the bisection (bisection.py) of what the ends leave in doubt; geometry/safety.py explains
the bound."""

from __future__ import annotations

import numpy as np
from numba import njit

from envfactory.geometry.kernels.bisection import capsule_motion_unproven, motion_pose
from envfactory.geometry.kernels.outcomes import DOUBT_AT_ENDS, DOUBT_BETWEEN, PROVEN
from envfactory.geometry.kernels.pose import (
    capsule_bounds,
)


@njit(cache=True, inline="always")
def travel_and_reserve(lever, way, gripper_change, travel, reserve):
    """Per row of lever arms (a shape's or a pair's): how far the arm's motion `way` can close it (each joint's
    lever times its change) and how far the gripper's can from its middle value (its lever times half the
    gripper's change; zero without a gripper column). Whether any reserve is not zero."""
    arm = way.shape[0]
    has_gripper = lever.shape[1] > arm
    moves = False
    for row in range(lever.shape[0]):
        total = 0.0
        for j in range(arm):
            total += lever[row, j] * abs(way[j])
        travel[row] = total
        reserve[row] = lever[row, arm] * (gripper_change / 2) if has_gripper else 0.0
        moves = moves or reserve[row] != 0.0
    return moves


@njit(cache=True)
def motion_proof(
    coordinates,
    q_from,
    way,
    gripper_middle,
    gripper_change,
    pair_lever,
    margin,
    reuse,
    last_q,
    last_bound,
    gripper_beyond,
    reuse_within,
    levels,
    deeper,
    parent,
    placement,
    kind,
    axis,
    coordinate,
    gain,
    shape_joint,
    local_ends,
    local_boxes,
    box_half,
    radius,
    padding,
    moving,
    obstacle_low,
    obstacle_high,
    self_a,
    self_b,
    travel,
    reserve,
    start_bound,
    end_bound,
    unproven,
):
    """The safety check's proof of a straight arm motion on capsule bounds alone, in one compiled call: per pair its
    travel (lever arm times each joint's change) and reserve (the gripper's lever times half its change); bounds at
    the start (the last accepted end's, less how far the arm and gripper are from it, when `reuse` and within
    `reuse_within`; else measured) and at the end, with the gripper at its middle value, less the reserve; then the
    lever-bound bisection (capsule_motion_unproven) of the pairs the two ends leave in doubt. Fills travel,
    reserve, start_bound, end_bound, and unproven (per pair: left unproven by the bisection); returns (outcome,
    whether the gripper's motion closes any pair)."""
    pairs, arm = pair_lever.shape[0], q_from.shape[0]
    has_gripper = pair_lever.shape[1] > arm
    moves = travel_and_reserve(pair_lever, way, gripper_change, travel, reserve)
    unproven[:] = False
    if has_gripper:
        coordinates[arm] = gripper_middle
    frames = np.empty((parent.shape[0], 3, 4))
    ends = np.empty((shape_joint.shape[0], 2, 3))
    is_placed = np.zeros(shape_joint.shape[0], dtype=np.bool_)
    if reuse:
        farthest = 0.0
        for p in range(pairs):
            moved = 0.0
            for j in range(arm):
                moved += pair_lever[p, j] * abs(q_from[j] - last_q[j])
            if has_gripper:
                moved += pair_lever[p, arm] * gripper_beyond
            start_bound[p] = last_bound[p] - moved
            farthest = max(farthest, moved)
        reuse = farthest <= reuse_within
    if not reuse:
        motion_pose(
            coordinates,
            0.0,
            q_from,
            way,
            parent,
            placement,
            kind,
            axis,
            coordinate,
            gain,
            shape_joint,
            local_ends,
            frames,
            ends,
            is_placed,
        )
        capsule_bounds(
            frames,
            shape_joint,
            local_ends,
            radius,
            local_boxes,
            box_half,
            padding,
            moving,
            obstacle_low,
            obstacle_high,
            self_a,
            self_b,
            start_bound,
        )
        for p in range(pairs):
            start_bound[p] -= reserve[p]
    motion_pose(
        coordinates,
        1.0,
        q_from,
        way,
        parent,
        placement,
        kind,
        axis,
        coordinate,
        gain,
        shape_joint,
        local_ends,
        frames,
        ends,
        is_placed,
    )
    capsule_bounds(
        frames,
        shape_joint,
        local_ends,
        radius,
        local_boxes,
        box_half,
        padding,
        moving,
        obstacle_low,
        obstacle_high,
        self_a,
        self_b,
        end_bound,
    )
    doubt_at_ends = False
    asked = np.empty(pairs, dtype=np.int64)  # the pairs the two ends leave in doubt between them
    weak = 0
    for p in range(pairs):
        end_bound[p] -= reserve[p]
        if start_bound[p] < margin[p] or end_bound[p] < margin[p]:
            doubt_at_ends = True
        if start_bound[p] + end_bound[p] - travel[p] * 1.0 < 2 * margin[p]:
            asked[weak] = p
            weak += 1
    if doubt_at_ends:
        return DOUBT_AT_ENDS, moves
    if weak == 0:
        return PROVEN, moves
    asked = asked[:weak]
    left = np.empty(weak, dtype=np.bool_)
    capsule_motion_unproven(
        coordinates,
        q_from,
        way,
        asked,
        start_bound,
        end_bound,
        travel,
        reserve,
        margin,
        levels,
        deeper,
        parent,
        placement,
        kind,
        axis,
        coordinate,
        gain,
        shape_joint,
        local_ends,
        local_boxes,
        box_half,
        radius,
        padding,
        moving,
        obstacle_low,
        obstacle_high,
        self_a,
        self_b,
        left,
    )
    outcome = PROVEN
    for i in range(weak):
        if left[i]:
            unproven[asked[i]] = True
            outcome = DOUBT_BETWEEN
    return outcome, moves
