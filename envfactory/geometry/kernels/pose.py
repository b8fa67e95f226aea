"""Lower bounds on every measured clearance at one configuration, compiled.

The safety check asks for these bounds at each pose it tries. For one arm (a dozen joints, a few hundred pairs)
the arithmetic is tiny; what numpy costs is its per-call overhead, dozens of small operations per pose. One
compiled pass does the forward kinematics of the shape-carrying joints, the capsule ends, the separation of each
capsule from each obstacle box, and the capsule-to-capsule distance of each self pair (box against box where the
capsules come close), in a few microseconds."""

from __future__ import annotations

import numpy as np
from numba import njit

from envfactory.geometry.kernels.joint_table import NO_BOUND
from envfactory.geometry.kernels.joints import placed_point


@njit(cache=True, inline="always")
def _segment_distance(ends, a, b):
    """Distance between the segments of shapes a and b (ends: shapes x 2 x 3), on scalars: small
    array temporaries would cost more than the arithmetic."""
    d1x, d1y, d1z = ends[a, 1, 0] - ends[a, 0, 0], ends[a, 1, 1] - ends[a, 0, 1], ends[a, 1, 2] - ends[a, 0, 2]
    d2x, d2y, d2z = ends[b, 1, 0] - ends[b, 0, 0], ends[b, 1, 1] - ends[b, 0, 1], ends[b, 1, 2] - ends[b, 0, 2]
    rx, ry, rz = ends[a, 0, 0] - ends[b, 0, 0], ends[a, 0, 1] - ends[b, 0, 1], ends[a, 0, 2] - ends[b, 0, 2]
    a2 = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    f = d2x * rx + d2y * ry + d2z * rz
    if a2 <= 1e-18 and e <= 1e-18:
        s, t = 0.0, 0.0
    elif a2 <= 1e-18:
        s, t = 0.0, min(max(f / e, 0.0), 1.0)
    else:
        c = d1x * rx + d1y * ry + d1z * rz
        if e <= 1e-18:
            s, t = min(max(-c / a2, 0.0), 1.0), 0.0
        else:
            b2 = d1x * d2x + d1y * d2y + d1z * d2z
            denominator = a2 * e - b2 * b2
            s = min(max((b2 * f - c * e) / denominator, 0.0), 1.0) if denominator > 1e-18 else 0.0
            t = (b2 * s + f) / e
            if t < 0.0:
                s, t = min(max(-c / a2, 0.0), 1.0), 0.0
            elif t > 1.0:
                s, t = min(max((b2 - c) / a2, 0.0), 1.0), 1.0
    gx, gy, gz = rx + d1x * s - d2x * t, ry + d1y * s - d2y * t, rz + d1z * s - d2z * t
    return np.sqrt(gx * gx + gy * gy + gz * gz)


@njit(cache=True, inline="always")
def capsule_ends(frames, shape_joint, local_ends, ends):
    """Each shape's capsule end points in the base frame (shapes x 2 x 3)."""
    for shape in range(shape_joint.shape[0]):
        frame = frames[shape_joint[shape]]
        for end in range(2):
            for i in range(3):
                ends[shape, end, i] = placed_point(
                    frame, local_ends[shape, end, 0], local_ends[shape, end, 1], local_ends[shape, end, 2], i
                )


@njit(cache=True)
def capsule_bounds(
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
    out,
):
    """Lower bounds on the clearance of every measured pair, in the order the collision model numbers
    them: each moving shape against each obstacle (the better of its capsule's and its box's), then the
    self pairs (capsule against capsule, and box against box where the capsules come close)."""
    ends = np.empty((shape_joint.shape[0], 2, 3))
    capsule_ends(frames, shape_joint, local_ends, ends)
    obstacles = obstacle_low.shape[0]
    placed = np.empty((shape_joint.shape[0], PLACED_ROWS, 3))
    is_placed = np.zeros(shape_joint.shape[0], dtype=np.bool_)
    for m in range(moving.shape[0]):
        shape = moving[m]
        for o in range(obstacles):
            out[m * obstacles + o] = scene_bound(
                frames,
                ends,
                shape,
                o,
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
    row = moving.shape[0] * obstacles
    for pair in range(self_a.shape[0]):
        out[row] = self_pair_bound(
            frames,
            ends,
            self_a[pair],
            self_b[pair],
            shape_joint,
            local_boxes,
            box_half,
            radius,
            padding,
            placed,
            is_placed,
        )
        row += 1


@njit(cache=True, inline="always")
def scene_bound(
    frames,
    ends,
    shape,
    o,
    shape_joint,
    local_boxes,
    box_half,
    radius,
    padding,
    obstacle_low,
    obstacle_high,
    placed,
    is_placed,
):
    """A lower bound on a moving shape's clearance from obstacle o: the separation of the obstacle from the shape's
    capsule, or from its box, along the obstacle box's own axes (which bounds the distance between two convex
    sets), whichever is the larger; where that is small, also the boxes' separation along the shape box's axes and
    their cross products with the obstacle's (a tilted link beside the obstacle's edge: its capsule and its extent
    along the base axes overlap the obstacle where the link is centimetres away). (The distance between the
    extents would be tighter beside the obstacle's edges, but costs a third of this pass over every pose's scene
    pairs, more than the queries it spares.)"""
    _place_box(frames, shape, shape_joint, local_boxes, box_half, placed, is_placed)
    capsule_apart, box_apart = -np.inf, -np.inf
    for k in range(3):
        low = min(ends[shape, 0, k], ends[shape, 1, k])
        high = max(ends[shape, 0, k], ends[shape, 1, k])
        capsule_apart = max(capsule_apart, low - obstacle_high[o, k], obstacle_low[o, k] - high)
        box_apart = max(
            box_apart, placed[shape, LOW, k] - obstacle_high[o, k], obstacle_low[o, k] - placed[shape, HIGH, k]
        )
    bound = max(capsule_apart - radius[shape], box_apart - padding[shape])
    if bound < BOX_BELOW:
        bound = max(
            bound, _box_obstacle_apart(placed, box_half, shape, o, obstacle_low, obstacle_high) - padding[shape]
        )
    return bound if bound >= 0.0 else NO_BOUND


@njit(cache=True, inline="always")
def _box_obstacle_apart(placed, box_half, shape, o, obstacle_low, obstacle_high):
    """The separation of the shape's placed box from obstacle o's along the box's 3 axes and the 9 cross products of
    those with the obstacle's axes (the base frame's): with the obstacle's own axes (the extents), the 15 axes that
    separate two boxes wherever they are apart."""
    dx = (obstacle_low[o, 0] + obstacle_high[o, 0]) / 2 - placed[shape, CENTER, 0]
    dy = (obstacle_low[o, 1] + obstacle_high[o, 1]) / 2 - placed[shape, CENTER, 1]
    dz = (obstacle_low[o, 2] + obstacle_high[o, 2]) / 2 - placed[shape, CENTER, 2]
    hx = (obstacle_high[o, 0] - obstacle_low[o, 0]) / 2
    hy = (obstacle_high[o, 1] - obstacle_low[o, 1]) / 2
    hz = (obstacle_high[o, 2] - obstacle_low[o, 2]) / 2
    apart = -np.inf
    for axis in range(3):
        ax, ay, az = placed[shape, AXES + axis, 0], placed[shape, AXES + axis, 1], placed[shape, AXES + axis, 2]
        for k in range(4):  # the box's own axis, then its cross product with each of the obstacle's
            if k == 0:
                nx, ny, nz = ax, ay, az
            elif k == 1:
                nx, ny, nz = 0.0, az, -ay
            elif k == 2:
                nx, ny, nz = -az, 0.0, ax
            else:
                nx, ny, nz = ay, -ax, 0.0
            length = np.sqrt(nx * nx + ny * ny + nz * nz)
            if length < 1e-9:  # parallel to an obstacle axis: the extents have it
                continue
            nx, ny, nz = nx / length, ny / length, nz / length
            apart = max(
                apart,
                abs(dx * nx + dy * ny + dz * nz)
                - _box_reach(placed, box_half, shape, nx, ny, nz)
                - hx * abs(nx)
                - hy * abs(ny)
                - hz * abs(nz),
            )
    return apart


@njit(cache=True, inline="always")
def toward(x0, y0, z0, x1, y1, z1, o, obstacle_low, obstacle_high):
    """The unit direction from obstacle o's nearest point to the middle of the box [x0, x1] x [y0, y1] x [z0, z1]
    (base frame), and how far the obstacle reaches along it (infinite where the middle lies inside the obstacle: no
    direction)."""
    cx, cy, cz = (x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2
    nx = cx - min(max(cx, obstacle_low[o, 0]), obstacle_high[o, 0])
    ny = cy - min(max(cy, obstacle_low[o, 1]), obstacle_high[o, 1])
    nz = cz - min(max(cz, obstacle_low[o, 2]), obstacle_high[o, 2])
    length = np.sqrt(nx * nx + ny * ny + nz * nz)
    if length < 1e-12:
        return 0.0, 0.0, 0.0, np.inf
    nx, ny, nz = nx / length, ny / length, nz / length
    reach = (
        max(nx * obstacle_low[o, 0], nx * obstacle_high[o, 0])
        + max(ny * obstacle_low[o, 1], ny * obstacle_high[o, 1])
        + max(nz * obstacle_low[o, 2], nz * obstacle_high[o, 2])
    )
    return nx, ny, nz, reach


@njit(cache=True, inline="always")
def aabb_gap(x0, y0, z0, x1, y1, z1, o, obstacle_low, obstacle_high):
    """The distance between the box [x0, x1] x [y0, y1] x [z0, z1] and obstacle o, both along the base frame's
    axes (the largest overlap, negative, where they overlap): a lower bound on the distance between anything
    inside them. Beside an edge of the obstacle the separation along one axis would count only one of its sides."""
    gx = max(x0 - obstacle_high[o, 0], obstacle_low[o, 0] - x1)
    gy = max(y0 - obstacle_high[o, 1], obstacle_low[o, 1] - y1)
    gz = max(z0 - obstacle_high[o, 2], obstacle_low[o, 2] - z1)
    if gx <= 0.0 and gy <= 0.0 and gz <= 0.0:
        return max(gx, gy, gz)
    gx, gy, gz = max(gx, 0.0), max(gy, 0.0), max(gz, 0.0)
    return np.sqrt(gx * gx + gy * gy + gz * gz)


# Below this capsule bound a self pair is also bounded by its two boxes: a flat base plate's capsule, or a long
# link's by the base it turns on, can overlap where the boxes are centimetres apart, and coal would be asked at
# every pose; above it the capsules already clear what a motion can close.
BOX_BELOW = 0.05


# rows of a placed box (capsule_bounds' `placed`): its centre, its three axes, and the corners of the box along the
# base frame's axes around it
CENTER, AXES, LOW, HIGH = 0, 1, 4, 5
PLACED_ROWS = 6


@njit(cache=True, inline="always")
def _place_box(frames, shape, shape_joint, local_boxes, box_half, placed, is_placed):
    """The shape's box in the base frame (placed[shape], rows CENTER to HIGH), once per pose."""
    if not is_placed[shape]:
        frame = frames[shape_joint[shape]]
        for i in range(3):
            placed[shape, CENTER, i] = placed_point(
                frame, local_boxes[shape, 0, 0], local_boxes[shape, 0, 1], local_boxes[shape, 0, 2], i
            )
            for axis in range(1, 4):
                placed[shape, axis, i] = (
                    frame[i, 0] * local_boxes[shape, axis, 0]
                    + frame[i, 1] * local_boxes[shape, axis, 1]
                    + frame[i, 2] * local_boxes[shape, axis, 2]
                )
        for i in range(3):  # along each of the base frame's axes
            reach = _box_reach(
                placed, box_half, shape, 1.0 if i == 0 else 0.0, 1.0 if i == 1 else 0.0, 1.0 if i == 2 else 0.0
            )
            placed[shape, LOW, i] = placed[shape, CENTER, i] - reach
            placed[shape, HIGH, i] = placed[shape, CENTER, i] + reach
        is_placed[shape] = True


@njit(cache=True, inline="always")
def _box_reach(placed, box_half, shape, nx, ny, nz):
    """How far the shape's box reaches from its centre along the unit direction n."""
    reach = 0.0
    for axis in range(3):
        row = AXES + axis
        reach += box_half[shape, axis] * abs(
            placed[shape, row, 0] * nx + placed[shape, row, 1] * ny + placed[shape, row, 2] * nz
        )
    return reach


@njit(cache=True, inline="always")
def self_pair_bound(frames, ends, a, b, shape_joint, local_boxes, box_half, radius, padding, placed, is_placed):
    """A lower bound on the clearance of two of the robot's shapes: their capsules' distance, or where that is
    small, the better of it and their boxes' separation along the boxes' 6 axes and the line between their centres
    (any direction separates two convex sets by at least the gap of their projections on it)."""
    bound = _segment_distance(ends, a, b) - radius[a] - radius[b]
    if bound < BOX_BELOW:
        _place_box(frames, a, shape_joint, local_boxes, box_half, placed, is_placed)
        _place_box(frames, b, shape_joint, local_boxes, box_half, placed, is_placed)
        dx = placed[b, CENTER, 0] - placed[a, CENTER, 0]
        dy = placed[b, CENTER, 1] - placed[a, CENTER, 1]
        dz = placed[b, CENTER, 2] - placed[a, CENTER, 2]
        apart = -np.inf
        for direction in range(7):
            if direction < 6:
                shape, axis = (a, AXES + direction) if direction < 3 else (b, AXES + direction - 3)
                nx, ny, nz = placed[shape, axis, 0], placed[shape, axis, 1], placed[shape, axis, 2]
            else:
                length = np.sqrt(dx * dx + dy * dy + dz * dz)
                if length < 1e-12:
                    continue
                nx, ny, nz = dx / length, dy / length, dz / length
            apart = max(
                apart,
                abs(dx * nx + dy * ny + dz * nz)
                - _box_reach(placed, box_half, a, nx, ny, nz)
                - _box_reach(placed, box_half, b, nx, ny, nz),
            )
        bound = max(bound, apart - padding[a] - padding[b])
    return bound if bound >= 0.0 else NO_BOUND


@njit(cache=True)
def shape_sphere_gaps(frames, shape_joint, local_ends, radius, shapes, center, sphere_radius, out):
    """out[i]: the gap between the capsule of shapes[i], placed by the frames, and a sphere, negative when they
    overlap: a lower bound on the gap between anything inside them."""
    ends = np.empty((1, 2, 3))
    for i in range(shapes.shape[0]):
        shape = shapes[i]
        frame = frames[shape_joint[shape]]
        for end in range(2):
            for k in range(3):
                ends[0, end, k] = placed_point(
                    frame, local_ends[shape, end, 0], local_ends[shape, end, 1], local_ends[shape, end, 2], k
                )
        out[i] = segment_point_distance(ends, 0, center) - radius[shape] - sphere_radius


@njit(cache=True, inline="always")
def segment_point_distance(ends, c, point):
    """Distance from a point to the segment of capsule c (ends: capsules x 2 x 3)."""
    ax, ay, az = ends[c, 1, 0] - ends[c, 0, 0], ends[c, 1, 1] - ends[c, 0, 1], ends[c, 1, 2] - ends[c, 0, 2]
    length2 = max(ax * ax + ay * ay + az * az, 1e-12)
    ox, oy, oz = point[0] - ends[c, 0, 0], point[1] - ends[c, 0, 1], point[2] - ends[c, 0, 2]
    t = min(max((ox * ax + oy * ay + oz * az) / length2, 0.0), 1.0)
    nx, ny, nz = ox - t * ax, oy - t * ay, oz - t * az
    return np.sqrt(nx * nx + ny * ny + nz * nz)
