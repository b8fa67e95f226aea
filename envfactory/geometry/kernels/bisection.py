"""The lever-bound bisection of a motion's pairs in doubt, compiled: where the capsule bounds at the two ends of
a straight joint-space motion leave a pair unproven, the motion is halved and each half judged by the bounds at
its ends less the levers' travel, to a depth; what no bound clears is left for coal (geometry/safety.py)."""

from __future__ import annotations

import numpy as np
from numba import njit

from envfactory.geometry.kernels.joint_table import NO_BOUND
from envfactory.geometry.kernels.joints import joint_frames
from envfactory.geometry.kernels.pose import PLACED_ROWS, capsule_ends, scene_bound, self_pair_bound


@njit(cache=True, inline="always")
def _pair_bound(
    frames,
    ends,
    pair,
    shape_joint,
    local_boxes,
    box_half,
    radius,
    padding,
    moving,
    obstacle_low,
    obstacle_high,
    self_a,
    self_b,
    placed,
    is_placed,
):
    """capsule_bounds' bound for one pair (its numbering: moving shape x obstacle, then the self pairs)."""
    obstacles = obstacle_low.shape[0]
    scene = moving.shape[0] * obstacles
    if pair >= scene:
        return self_pair_bound(
            frames,
            ends,
            self_a[pair - scene],
            self_b[pair - scene],
            shape_joint,
            local_boxes,
            box_half,
            radius,
            padding,
            placed,
            is_placed,
        )
    return scene_bound(
        frames,
        ends,
        moving[pair // obstacles],
        pair % obstacles,
        shape_joint,
        local_boxes,
        box_half,
        radius,
        padding,
        obstacle_low,
        obstacle_high,
        placed,
        is_placed,
    )


@njit(cache=True, inline="always")
def motion_pose(
    coordinates,
    fraction,
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
):
    """Frames and capsule ends with the arm `fraction` of the way along the motion (boxes placed on demand)."""
    for j in range(q_from.shape[0]):
        coordinates[j] = q_from[j] + fraction * way[j]
    joint_frames(coordinates, parent, placement, kind, axis, coordinate, gain, frames)
    capsule_ends(frames, shape_joint, local_ends, ends)
    is_placed[:] = False


@njit(cache=True)
def capsule_motion_unproven(
    coordinates,
    q_from,
    way,
    pairs,
    start_bound,
    end_bound,
    travel,
    reserve,
    threshold,
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
    unproven,
):
    """The lever-bound bisection of a straight arm motion on capsule bounds alone (less each pair's reserve), for
    these pairs. Each of the first `levels` halves every piece and poses the arm once at each new point (the gripper
    where `coordinates` holds it), shared by the pairs; the pieces a pair still leaves unproven are then halved
    `deeper` times more, posed for that pair alone. A pair is proven once every piece's two end bounds less the
    piece's travel keep twice its threshold; unproven[i] says pairs[i] was not (or capsules overlap)."""
    count = pairs.shape[0]
    points = 2**levels + 1
    grid = np.empty((count, points))
    active = np.empty(count, dtype=np.bool_)  # still worth halving: unproven, no overlap met
    frames = np.empty((parent.shape[0], 3, 4))
    ends = np.empty((shape_joint.shape[0], 2, 3))
    placed = np.empty((shape_joint.shape[0], PLACED_ROWS, 3))
    is_placed = np.zeros(shape_joint.shape[0], dtype=np.bool_)
    alive = 0
    for i in range(count):
        pair = pairs[i]
        grid[i, 0], grid[i, points - 1] = start_bound[pair], end_bound[pair]
        unproven[i] = True
        active[i] = grid[i, 0] > NO_BOUND and grid[i, points - 1] > NO_BOUND
        alive += active[i]
    for level in range(1, levels + 1):
        if alive == 0:
            break
        spacing = 2 ** (levels - level)
        for k in range(1, 2**level, 2):
            motion_pose(
                coordinates,
                k / 2**level,
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
            for i in range(count):
                if active[i]:
                    pair = pairs[i]
                    grid[i, k * spacing] = (
                        _pair_bound(
                            frames,
                            ends,
                            pair,
                            shape_joint,
                            local_boxes,
                            box_half,
                            radius,
                            padding,
                            moving,
                            obstacle_low,
                            obstacle_high,
                            self_a,
                            self_b,
                            placed,
                            is_placed,
                        )
                        - reserve[pair]
                    )
        length = 1.0 / 2**level
        for i in range(count):
            if not active[i]:
                continue
            pair = pairs[i]
            proven = True
            for piece in range(2**level):
                a, b = grid[i, piece * spacing], grid[i, (piece + 1) * spacing]
                if a == NO_BOUND or b == NO_BOUND:  # overlapping capsules: no halving can prove it
                    active[i] = False
                    proven = False
                    break
                if a + b - travel[pair] * length < 2.0 * threshold[pair]:
                    proven = False
            if proven:
                unproven[i] = False
                active[i] = False
            if not active[i]:
                alive -= 1
    # the pieces a pair leaves, halved on their own: (start, its bound, end, its bound, halvings left)
    stack = np.empty((deeper + 2, 5))
    last = 2**levels
    for i in range(count):
        if not active[i]:
            continue
        pair = pairs[i]
        proven = True
        for piece in range(last):
            if not proven:
                break
            stack[0, 0], stack[0, 1] = piece / last, grid[i, piece]
            stack[0, 2], stack[0, 3], stack[0, 4] = (piece + 1) / last, grid[i, piece + 1], deeper
            top = 1
            while top > 0:
                top -= 1
                a, bound_a, b, bound_b, left = stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3], stack[top, 4]
                if bound_a + bound_b - travel[pair] * (b - a) >= 2.0 * threshold[pair]:
                    continue
                if left == 0 or bound_a == NO_BOUND or bound_b == NO_BOUND:
                    proven = False
                    break
                middle = (a + b) / 2
                motion_pose(
                    coordinates,
                    middle,
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
                bound = (
                    _pair_bound(
                        frames,
                        ends,
                        pair,
                        shape_joint,
                        local_boxes,
                        box_half,
                        radius,
                        padding,
                        moving,
                        obstacle_low,
                        obstacle_high,
                        self_a,
                        self_b,
                        placed,
                        is_placed,
                    )
                    - reserve[pair]
                )
                stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3], stack[top, 4] = (
                    a,
                    bound_a,
                    middle,
                    bound,
                    left - 1,
                )
                stack[top + 1, 0], stack[top + 1, 1] = middle, bound
                stack[top + 1, 2], stack[top + 1, 3], stack[top + 1, 4] = b, bound_b, left - 1
                top += 2
        unproven[i] = not proven
