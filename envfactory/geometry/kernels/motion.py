"""The proof of a whole motion, compiled: each pair's travel and reserve along the straight joint-space line,
the bounds at its ends, and the lever-bound bisection of what the ends leave in doubt (geometry/safety.py
explains the bound); and the same for a motion against the objects' bounding spheres."""

from __future__ import annotations

import numpy as np
from numba import njit

from envfactory.geometry.kernels.joints import NO_BOUND, joint_frames
from envfactory.geometry.kernels.pose import (
    PLACED_ROWS,
    capsule_bounds,
    capsule_ends,
    scene_bound,
    segment_point_distance,
    self_pair_bound,
)


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
def _motion_pose(
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
            _motion_pose(
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
                _motion_pose(
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


@njit(cache=True, inline="always")
def _sphere_gaps_at(
    fraction,
    coordinates,
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
    moving,
    radius,
    reserve,
    centers,
    radii,
    frames,
    ends,
    out,
):
    """out[m, s]: the gap of moving shape m's capsule from sphere s, less the shape's reserve, with the arm
    `fraction` of the way along the motion."""
    for j in range(q_from.shape[0]):
        coordinates[j] = q_from[j] + fraction * way[j]
    joint_frames(coordinates, parent, placement, kind, axis, coordinate, gain, frames)
    capsule_ends(frames, shape_joint, local_ends, ends)
    for m in range(moving.shape[0]):
        shape = moving[m]
        for s in range(centers.shape[0]):
            out[m, s] = segment_point_distance(ends, shape, centers[s]) - radius[shape] - radii[s] - reserve[m]


@njit(cache=True, inline="always")
def _travel_and_reserve(lever, way, gripper_change, travel, reserve):
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
def motion_clear_of_spheres(
    coordinates,
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
    moving,
    radius,
    lever,
    gripper_change,
    world_centers,
    base_in_world,
    radii,
    margin,
    levels,
):
    """Whether every moving shape's capsule stays `margin` from every sphere (centres in the world) along the
    straight arm motion q_from + f way, the gripper anywhere within `gripper_change` of where `coordinates` holds
    it: each shape's travel is its lever arms times the joints' changes, its reserve its gripper lever times half
    the gripper's change; the lever bound on pieces halved where their two end gaps cannot prove it, down to
    2**-levels of the motion, refused at any pose measured inside."""
    travel, reserve = np.empty(moving.shape[0]), np.empty(moving.shape[0])
    _travel_and_reserve(lever, way, gripper_change, travel, reserve)
    centers = np.empty_like(world_centers)
    for s in range(world_centers.shape[0]):
        for i in range(3):
            centers[s, i] = world_centers[s, i] - base_in_world[i]  # base frame: the mount is a translation
    points = 2**levels + 1
    grid = np.empty((points, moving.shape[0], centers.shape[0]))
    frames = np.empty((parent.shape[0], 3, 4))
    ends = np.empty((shape_joint.shape[0], 2, 3))
    _sphere_gaps_at(
        0.0,
        coordinates,
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
        moving,
        radius,
        reserve,
        centers,
        radii,
        frames,
        ends,
        grid[0],
    )
    clear = True
    for m in range(moving.shape[0]):
        for s in range(centers.shape[0]):
            if grid[0, m, s] - travel[m] < margin:
                clear = False
    if clear:
        return True
    last = points - 1
    _sphere_gaps_at(
        1.0,
        coordinates,
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
        moving,
        radius,
        reserve,
        centers,
        radii,
        frames,
        ends,
        grid[last],
    )
    stack = np.empty((2 * points, 2), dtype=np.int64)
    stack[0, 0], stack[0, 1] = 0, last
    top = 1
    while top > 0:
        top -= 1
        a, b = stack[top, 0], stack[top, 1]
        length = (b - a) / last
        proven = True
        for m in range(moving.shape[0]):
            for s in range(centers.shape[0]):
                if grid[a, m, s] + grid[b, m, s] - travel[m] * length < 2.0 * margin:
                    proven = False
        if proven:
            continue
        if b - a == 1:
            return False
        middle = (a + b) // 2
        _sphere_gaps_at(
            middle / last,
            coordinates,
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
            moving,
            radius,
            reserve,
            centers,
            radii,
            frames,
            ends,
            grid[middle],
        )
        for m in range(moving.shape[0]):
            for s in range(centers.shape[0]):
                if grid[middle, m, s] < margin:
                    return False
        stack[top, 0], stack[top, 1] = a, middle
        stack[top + 1, 0], stack[top + 1, 1] = middle, b
        top += 2
    return True


# motion_proof's outcomes: the capsules prove the whole motion; a pair is in doubt at its start or end (below its
# margin there: coal must measure it); the ends hold but the compiled pass leaves pairs unproven between them
PROVEN, DOUBT_AT_ENDS, DOUBT_BETWEEN = 0, 1, 2


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
    moves = _travel_and_reserve(pair_lever, way, gripper_change, travel, reserve)
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
        _motion_pose(
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
    _motion_pose(
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
