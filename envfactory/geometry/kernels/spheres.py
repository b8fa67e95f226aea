"""The proof that a whole motion keeps the arm clear of the task's objects, compiled: each moving shape's capsule
against each object's bounding sphere along the straight joint-space line, bisected by the same lever bound
the safety proof uses (geometry/object_clearance.py asks it before a cycle is played without dynamics)."""

from __future__ import annotations

import numpy as np
from numba import njit

from envfactory.geometry.kernels.joints import joint_frames
from envfactory.geometry.kernels.motion import travel_and_reserve
from envfactory.geometry.kernels.pose import capsule_ends, segment_point_distance


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
    travel_and_reserve(lever, way, gripper_change, travel, reserve)
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
