"""A finger's clearance over a gripper range at one pose, compiled: its box corners tabulated in its mount's frame
(geometry/gripper_sweep.py), placed by the mount, separated from an obstacle box or an arm link's box."""

from __future__ import annotations

import numpy as np
from numba import njit

from envfactory.geometry.kernels.joints import placed_point
from envfactory.geometry.kernels.pose import aabb_gap, toward


@njit(cache=True, inline="always")
def _place_sweep(frame, sweep_corners, row, first, last, placed, low, high):
    """A finger's box corners at gripper samples first..last (tabulated in its mount's frame), placed by the
    mount's frame into placed[:corners], and their extent along the base frame's axes."""
    low[:] = np.inf
    high[:] = -np.inf
    for sample in range(first, last + 1):
        for corner in range(8):
            k = 8 * (sample - first) + corner
            x, y, z = (
                sweep_corners[row, sample, corner, 0],
                sweep_corners[row, sample, corner, 1],
                sweep_corners[row, sample, corner, 2],
            )
            for i in range(3):
                value = placed_point(frame, x, y, z, i)
                placed[k, i] = value
                low[i] = min(low[i], value)
                high[i] = max(high[i], value)


@njit(cache=True, inline="always")
def _sweep_gap(
    frames, placed, low, high, corners, obstacle, obstacle_low, obstacle_high, other, other_joint, local_corners, box
):
    """The distance of placed swept corners' extent from an obstacle (obstacle >= 0), or their separation from
    another shape's box along the box's axes: it bounds the distance between their convex hull and the obstacle
    or box."""
    if obstacle >= 0:
        apart = aabb_gap(low[0], low[1], low[2], high[0], high[1], high[2], obstacle, obstacle_low, obstacle_high)
        if apart <= 0.0:
            return apart
        # a finger tilted beside an edge of the obstacle leaves its extent's corner empty: the direction from the
        # obstacle's nearest point to the extent's middle separates them by about their true distance
        nx, ny, nz, reach = toward(
            low[0], low[1], low[2], high[0], high[1], high[2], obstacle, obstacle_low, obstacle_high
        )
        if reach == np.inf:
            return apart
        lowest = np.inf
        for k in range(corners):
            lowest = min(lowest, placed[k, 0] * nx + placed[k, 1] * ny + placed[k, 2] * nz)
        return max(apart, lowest - reach)
    apart = -np.inf
    frame = frames[other_joint]
    for corner in range(8):
        for i in range(3):
            box[corner, i] = placed_point(
                frame,
                local_corners[other, corner, 0],
                local_corners[other, corner, 1],
                local_corners[other, corner, 2],
                i,
            )
    # the box's edges from its first corner (fit_box's order: x-, y- and z-steps are 4, 2 and 1)
    for edge in range(3):
        step = 4 >> edge
        ux, uy, uz = box[step, 0] - box[0, 0], box[step, 1] - box[0, 1], box[step, 2] - box[0, 2]
        length = np.sqrt(ux * ux + uy * uy + uz * uz)
        if length < 1e-12:
            continue
        ux, uy, uz = ux / length, uy / length, uz / length
        box_low, box_high = np.inf, -np.inf
        for corner in range(8):
            value = box[corner, 0] * ux + box[corner, 1] * uy + box[corner, 2] * uz
            box_low, box_high = min(box_low, value), max(box_high, value)
        lowest, highest = np.inf, -np.inf
        for k in range(corners):
            value = placed[k, 0] * ux + placed[k, 1] * uy + placed[k, 2] * uz
            lowest, highest = min(lowest, value), max(highest, value)
        apart = max(apart, lowest - box_high, box_low - highest)
    return apart


@njit(cache=True)
def swept_box_gaps(
    frames,
    mount_joint,
    sweep_corners,
    first,
    last,
    rows,
    obstacles,
    obstacle_low,
    obstacle_high,
    others,
    other_joint,
    local_corners,
    out,
):
    """For each pair, a finger's box corners at gripper samples first..last (tabulated in the frame of the
    joint they are mounted on) against either an obstacle (obstacles[p] >= 0) or another shape's box
    (others[p]): their separation along the obstacle's or the box's axes, which bounds the distance
    between the convex hull of the corners and the obstacle or box."""
    count, corners = sweep_corners.shape[0], 8 * (last - first + 1)
    placed = np.empty((count, corners, 3))
    low, high = np.empty((count, 3)), np.empty((count, 3))
    done = np.zeros(count, dtype=np.bool_)
    box = np.empty((8, 3))
    for p in range(rows.shape[0]):
        row = rows[p]
        if not done[row]:  # a finger measured against several obstacles is placed once
            _place_sweep(frames[mount_joint[row]], sweep_corners, row, first, last, placed[row], low[row], high[row])
            done[row] = True
        out[p] = _sweep_gap(
            frames,
            placed[row],
            low[row],
            high[row],
            corners,
            obstacles[p],
            obstacle_low,
            obstacle_high,
            others[p],
            other_joint[p],
            local_corners,
            box,
        )


@njit(cache=True)
def swept_box_gap(
    frames,
    mount_joint,
    sweep_corners,
    first,
    last,
    row,
    obstacle,
    obstacle_low,
    obstacle_high,
    other,
    other_joint,
    local_corners,
):
    """swept_box_gaps for one pair, on scalars: the safety check's deep bisections ask for one pair at a time."""
    corners = 8 * (last - first + 1)
    placed = np.empty((corners, 3))
    low, high, box = np.empty(3), np.empty(3), np.empty((8, 3))
    _place_sweep(frames[mount_joint[row]], sweep_corners, row, first, last, placed, low, high)
    return _sweep_gap(
        frames,
        placed,
        low,
        high,
        corners,
        obstacle,
        obstacle_low,
        obstacle_high,
        other,
        other_joint,
        local_corners,
        box,
    )
