"""Lower bounds on every measured clearance at one configuration, compiled.

The safety check asks for these bounds at each pose it tries. For one arm
(a dozen joints, a few hundred pairs) the arithmetic is tiny; what numpy
costs is its per-call overhead, dozens of small operations per pose. One
compiled pass does the forward kinematics of the shape-carrying joints, the
capsule ends, the separation of each capsule from each obstacle box, and the
capsule-to-capsule distance of each self pair (box against box where the
capsules come close), in a few microseconds.

Numba compiles this on first use and caches the result next to the module.
The helpers a loop calls per pair or per pose are inlined: a compiled call that
passes a dozen arrays costs more (about 0.1 µs) than the arithmetic it runs.
"""

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
        raise ValueError(f"joint {model.names[joint]!r} ({joint_model.shortname()}) is driven but is not "
                         f"a one-coordinate revolute or prismatic joint")
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
    raise ValueError(f"joint {model.names[joint]!r} ({joint_model.shortname()}) is neither a plain revolute "
                     f"nor a plain prismatic joint")


@njit(cache=True, inline="always")
def _compose(up, local, out):
    """out = up * local for 3x4 rigid transforms [R | t] (written out: numba's @ would need BLAS)."""
    for i in range(3):
        for j in range(4):
            value = up[i, 0] * local[0, j] + up[i, 1] * local[1, j] + up[i, 2] * local[2, j]
            out[i, j] = value + up[i, 3] if j == 3 else value


@njit(cache=True, inline="always")
def _placed(frame, x, y, z, i):
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
                ends[shape, end, i] = _placed(frame, local_ends[shape, end, 0], local_ends[shape, end, 1],
                                              local_ends[shape, end, 2], i)


@njit(cache=True)
def capsule_bounds(frames, shape_joint, local_ends, radius, local_boxes, box_half, padding, moving, obstacle_low,
                   obstacle_high, self_a, self_b, out):
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
            out[m * obstacles + o] = _scene_bound(frames, ends, shape, o, shape_joint, local_boxes, box_half, radius,
                                                  padding, obstacle_low, obstacle_high, placed, is_placed)
    row = moving.shape[0] * obstacles
    for pair in range(self_a.shape[0]):
        out[row] = _self_pair_bound(frames, ends, self_a[pair], self_b[pair], shape_joint, local_boxes, box_half,
                                    radius, padding, placed, is_placed)
        row += 1


@njit(cache=True, inline="always")
def _scene_bound(frames, ends, shape, o, shape_joint, local_boxes, box_half, radius, padding, obstacle_low,
                 obstacle_high, placed, is_placed):
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
        box_apart = max(box_apart, placed[shape, LOW, k] - obstacle_high[o, k], obstacle_low[o, k] - placed[shape, HIGH, k])
    bound = max(capsule_apart - radius[shape], box_apart - padding[shape])
    if bound < BOX_BELOW:
        bound = max(bound, _box_obstacle_apart(placed, box_half, shape, o, obstacle_low, obstacle_high) - padding[shape])
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
            apart = max(apart, abs(dx * nx + dy * ny + dz * nz) - _box_reach(placed, box_half, shape, nx, ny, nz)
                        - hx * abs(nx) - hy * abs(ny) - hz * abs(nz))
    return apart


@njit(cache=True, inline="always")
def _toward(x0, y0, z0, x1, y1, z1, o, obstacle_low, obstacle_high):
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
    reach = (max(nx * obstacle_low[o, 0], nx * obstacle_high[o, 0]) + max(ny * obstacle_low[o, 1], ny * obstacle_high[o, 1])
             + max(nz * obstacle_low[o, 2], nz * obstacle_high[o, 2]))
    return nx, ny, nz, reach


@njit(cache=True, inline="always")
def _aabb_gap(x0, y0, z0, x1, y1, z1, o, obstacle_low, obstacle_high):
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
            placed[shape, CENTER, i] = _placed(frame, local_boxes[shape, 0, 0], local_boxes[shape, 0, 1],
                                               local_boxes[shape, 0, 2], i)
            for axis in range(1, 4):
                placed[shape, axis, i] = (frame[i, 0] * local_boxes[shape, axis, 0]
                                          + frame[i, 1] * local_boxes[shape, axis, 1]
                                          + frame[i, 2] * local_boxes[shape, axis, 2])
        for i in range(3):  # along each of the base frame's axes
            reach = _box_reach(placed, box_half, shape, 1.0 if i == 0 else 0.0, 1.0 if i == 1 else 0.0,
                               1.0 if i == 2 else 0.0)
            placed[shape, LOW, i] = placed[shape, CENTER, i] - reach
            placed[shape, HIGH, i] = placed[shape, CENTER, i] + reach
        is_placed[shape] = True


@njit(cache=True, inline="always")
def _box_reach(placed, box_half, shape, nx, ny, nz):
    """How far the shape's box reaches from its centre along the unit direction n."""
    reach = 0.0
    for axis in range(3):
        row = AXES + axis
        reach += box_half[shape, axis] * abs(placed[shape, row, 0] * nx + placed[shape, row, 1] * ny
                                             + placed[shape, row, 2] * nz)
    return reach


@njit(cache=True, inline="always")
def _self_pair_bound(frames, ends, a, b, shape_joint, local_boxes, box_half, radius, padding, placed, is_placed):
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
            apart = max(apart, abs(dx * nx + dy * ny + dz * nz) - _box_reach(placed, box_half, a, nx, ny, nz)
                        - _box_reach(placed, box_half, b, nx, ny, nz))
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
                ends[0, end, k] = _placed(frame, local_ends[shape, end, 0], local_ends[shape, end, 1],
                                          local_ends[shape, end, 2], k)
        out[i] = _segment_point_distance(ends, 0, center) - radius[shape] - sphere_radius


@njit(cache=True, inline="always")
def _segment_point_distance(ends, c, point):
    """Distance from a point to the segment of capsule c (ends: capsules x 2 x 3)."""
    ax, ay, az = ends[c, 1, 0] - ends[c, 0, 0], ends[c, 1, 1] - ends[c, 0, 1], ends[c, 1, 2] - ends[c, 0, 2]
    length2 = max(ax * ax + ay * ay + az * az, 1e-12)
    ox, oy, oz = point[0] - ends[c, 0, 0], point[1] - ends[c, 0, 1], point[2] - ends[c, 0, 2]
    t = min(max((ox * ax + oy * ay + oz * az) / length2, 0.0), 1.0)
    nx, ny, nz = ox - t * ax, oy - t * ay, oz - t * az
    return np.sqrt(nx * nx + ny * ny + nz * nz)


@njit(cache=True, inline="always")
def _place_sweep(frame, sweep_corners, row, first, last, placed, low, high):
    """A finger's box corners at gripper samples first..last (tabulated in its mount's frame), placed by the
    mount's frame into placed[:corners], and their extent along the base frame's axes."""
    low[:] = np.inf
    high[:] = -np.inf
    for sample in range(first, last + 1):
        for corner in range(8):
            k = 8 * (sample - first) + corner
            x, y, z = (sweep_corners[row, sample, corner, 0], sweep_corners[row, sample, corner, 1],
                       sweep_corners[row, sample, corner, 2])
            for i in range(3):
                value = _placed(frame, x, y, z, i)
                placed[k, i] = value
                low[i] = min(low[i], value)
                high[i] = max(high[i], value)


@njit(cache=True, inline="always")
def _sweep_gap(frames, placed, low, high, corners, obstacle, obstacle_low, obstacle_high, other, other_joint,
               local_corners, box):
    """The distance of placed swept corners' extent from an obstacle (obstacle >= 0), or their separation from
    another shape's box along the box's axes: it bounds the distance between their convex hull and the obstacle
    or box."""
    if obstacle >= 0:
        apart = _aabb_gap(low[0], low[1], low[2], high[0], high[1], high[2], obstacle, obstacle_low, obstacle_high)
        if apart <= 0.0:
            return apart
        # a finger tilted beside an edge of the obstacle leaves its extent's corner empty: the direction from the
        # obstacle's nearest point to the extent's middle separates them by about their true distance
        nx, ny, nz, reach = _toward(low[0], low[1], low[2], high[0], high[1], high[2], obstacle, obstacle_low,
                                    obstacle_high)
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
            box[corner, i] = _placed(frame, local_corners[other, corner, 0], local_corners[other, corner, 1],
                                     local_corners[other, corner, 2], i)
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
def swept_box_gaps(frames, mount_joint, sweep_corners, first, last, rows, obstacles, obstacle_low, obstacle_high,
                   others, other_joint, local_corners, out):
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
        out[p] = _sweep_gap(frames, placed[row], low[row], high[row], corners, obstacles[p], obstacle_low,
                            obstacle_high, others[p], other_joint[p], local_corners, box)


@njit(cache=True)
def swept_box_gap(frames, mount_joint, sweep_corners, first, last, row, obstacle, obstacle_low, obstacle_high, other,
                  other_joint, local_corners):
    """swept_box_gaps for one pair, on scalars: the safety check's deep bisections ask for one pair at a time."""
    corners = 8 * (last - first + 1)
    placed = np.empty((corners, 3))
    low, high, box = np.empty(3), np.empty(3), np.empty((8, 3))
    _place_sweep(frames[mount_joint[row]], sweep_corners, row, first, last, placed, low, high)
    return _sweep_gap(frames, placed, low, high, corners, obstacle, obstacle_low, obstacle_high, other, other_joint,
                      local_corners, box)


@njit(cache=True, inline="always")
def _pair_bound(frames, ends, pair, shape_joint, local_boxes, box_half, radius, padding, moving, obstacle_low,
                obstacle_high, self_a, self_b, placed, is_placed):
    """capsule_bounds' bound for one pair (its numbering: moving shape x obstacle, then the self pairs)."""
    obstacles = obstacle_low.shape[0]
    scene = moving.shape[0] * obstacles
    if pair >= scene:
        return _self_pair_bound(frames, ends, self_a[pair - scene], self_b[pair - scene], shape_joint, local_boxes,
                                box_half, radius, padding, placed, is_placed)
    return _scene_bound(frames, ends, moving[pair // obstacles], pair % obstacles, shape_joint, local_boxes,
                        box_half, radius, padding, obstacle_low, obstacle_high, placed, is_placed)


@njit(cache=True, inline="always")
def _motion_pose(coordinates, fraction, q_from, way, parent, placement, kind, axis, coordinate, gain, shape_joint,
                 local_ends, frames, ends, is_placed):
    """Frames and capsule ends with the arm `fraction` of the way along the motion (boxes placed on demand)."""
    for j in range(q_from.shape[0]):
        coordinates[j] = q_from[j] + fraction * way[j]
    joint_frames(coordinates, parent, placement, kind, axis, coordinate, gain, frames)
    capsule_ends(frames, shape_joint, local_ends, ends)
    is_placed[:] = False


@njit(cache=True)
def capsule_motion_unproven(coordinates, q_from, way, pairs, start_bound, end_bound, travel, reserve, threshold,
                            levels, deeper, parent, placement, kind, axis, coordinate, gain, shape_joint, local_ends,
                            local_boxes, box_half, radius, padding, moving, obstacle_low, obstacle_high, self_a,
                            self_b, unproven):
    """The lever-bound bisection of a straight arm motion on capsule bounds alone (less each pair's reserve), for
    these pairs. Each of the first `levels` halves every piece and poses the arm once at each new point (the gripper
    where `coordinates` holds it), shared by the pairs; the pieces a pair still leaves unproven are then halved
    `deeper` times more, posed for that pair alone. A pair is proven once every piece's two end bounds less the
    piece's travel keep twice its threshold; unproven[i] says pairs[i] was not (or capsules overlap)."""
    count = pairs.shape[0]
    points = 2 ** levels + 1
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
        for k in range(1, 2 ** level, 2):
            _motion_pose(coordinates, k / 2 ** level, q_from, way, parent, placement, kind, axis, coordinate, gain,
                         shape_joint, local_ends, frames, ends, is_placed)
            for i in range(count):
                if active[i]:
                    pair = pairs[i]
                    grid[i, k * spacing] = _pair_bound(frames, ends, pair, shape_joint, local_boxes, box_half,
                                                       radius, padding, moving, obstacle_low, obstacle_high, self_a,
                                                       self_b, placed, is_placed) - reserve[pair]
        length = 1.0 / 2 ** level
        for i in range(count):
            if not active[i]:
                continue
            pair = pairs[i]
            proven = True
            for piece in range(2 ** level):
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
    last = 2 ** levels
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
                _motion_pose(coordinates, middle, q_from, way, parent, placement, kind, axis, coordinate, gain,
                             shape_joint, local_ends, frames, ends, is_placed)
                bound = _pair_bound(frames, ends, pair, shape_joint, local_boxes, box_half, radius, padding, moving,
                                    obstacle_low, obstacle_high, self_a, self_b, placed, is_placed) - reserve[pair]
                stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3], stack[top, 4] = a, bound_a, middle, bound, left - 1
                stack[top + 1, 0], stack[top + 1, 1] = middle, bound
                stack[top + 1, 2], stack[top + 1, 3], stack[top + 1, 4] = b, bound_b, left - 1
                top += 2
        unproven[i] = not proven


@njit(cache=True, inline="always")
def _sphere_gaps_at(fraction, coordinates, q_from, way, parent, placement, kind, axis, coordinate, gain, shape_joint,
                    local_ends, moving, radius, reserve, centers, radii, frames, ends, out):
    """out[m, s]: the gap of moving shape m's capsule from sphere s, less the shape's reserve, with the arm
    `fraction` of the way along the motion."""
    for j in range(q_from.shape[0]):
        coordinates[j] = q_from[j] + fraction * way[j]
    joint_frames(coordinates, parent, placement, kind, axis, coordinate, gain, frames)
    capsule_ends(frames, shape_joint, local_ends, ends)
    for m in range(moving.shape[0]):
        shape = moving[m]
        for s in range(centers.shape[0]):
            out[m, s] = _segment_point_distance(ends, shape, centers[s]) - radius[shape] - radii[s] - reserve[m]


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
def motion_clear_of_spheres(coordinates, q_from, way, parent, placement, kind, axis, coordinate, gain, shape_joint,
                            local_ends, moving, radius, lever, gripper_change, world_centers, base_in_world, radii,
                            margin, levels):
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
    points = 2 ** levels + 1
    grid = np.empty((points, moving.shape[0], centers.shape[0]))
    frames = np.empty((parent.shape[0], 3, 4))
    ends = np.empty((shape_joint.shape[0], 2, 3))
    _sphere_gaps_at(0.0, coordinates, q_from, way, parent, placement, kind, axis, coordinate, gain, shape_joint,
                    local_ends, moving, radius, reserve, centers, radii, frames, ends, grid[0])
    clear = True
    for m in range(moving.shape[0]):
        for s in range(centers.shape[0]):
            if grid[0, m, s] - travel[m] < margin:
                clear = False
    if clear:
        return True
    last = points - 1
    _sphere_gaps_at(1.0, coordinates, q_from, way, parent, placement, kind, axis, coordinate, gain, shape_joint,
                    local_ends, moving, radius, reserve, centers, radii, frames, ends, grid[last])
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
        _sphere_gaps_at(middle / last, coordinates, q_from, way, parent, placement, kind, axis, coordinate, gain,
                        shape_joint, local_ends, moving, radius, reserve, centers, radii, frames, ends, grid[middle])
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
def motion_proof(coordinates, q_from, way, gripper_middle, gripper_change, pair_lever, margin, reuse, last_q,
                 last_bound, gripper_beyond, reuse_within, levels, deeper, parent, placement, kind, axis, coordinate,
                 gain, shape_joint, local_ends, local_boxes, box_half, radius, padding, moving, obstacle_low,
                 obstacle_high, self_a, self_b, travel, reserve, start_bound, end_bound, unproven):
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
        _motion_pose(coordinates, 0.0, q_from, way, parent, placement, kind, axis, coordinate, gain, shape_joint,
                     local_ends, frames, ends, is_placed)
        capsule_bounds(frames, shape_joint, local_ends, radius, local_boxes, box_half, padding, moving, obstacle_low,
                       obstacle_high, self_a, self_b, start_bound)
        for p in range(pairs):
            start_bound[p] -= reserve[p]
    _motion_pose(coordinates, 1.0, q_from, way, parent, placement, kind, axis, coordinate, gain, shape_joint,
                 local_ends, frames, ends, is_placed)
    capsule_bounds(frames, shape_joint, local_ends, radius, local_boxes, box_half, padding, moving, obstacle_low,
                   obstacle_high, self_a, self_b, end_bound)
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
    capsule_motion_unproven(coordinates, q_from, way, asked, start_bound, end_bound, travel, reserve, margin, levels,
                            deeper, parent, placement, kind, axis, coordinate, gain, shape_joint, local_ends,
                            local_boxes, box_half, radius, padding, moving, obstacle_low, obstacle_high, self_a,
                            self_b, left)
    outcome = PROVEN
    for i in range(weak):
        if left[i]:
            unproven[asked[i]] = True
            outcome = DOUBT_BETWEEN
    return outcome, moves
