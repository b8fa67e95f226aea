"""The robot's collision shapes as the safety proof sees them: each URDF shape, the capsule and the box fitted
around it (in its parent joint's frame), and the fitting itself."""

from __future__ import annotations

import itertools
import math
import random
from dataclasses import dataclass
from functools import cached_property

import coal
import numpy as np


@dataclass(frozen=True)
class Shape:
    """One collision shape of the robot, with the capsule and the box that enclose it (parent joint frame)."""

    name: str
    link: str
    joint: int  # Pinocchio joint the shape rides on; 0 for the fixed base
    capsule_start: np.ndarray
    capsule_end: np.ndarray
    radius: float  # capsule radius, padding included
    padding: float
    box: tuple[np.ndarray, np.ndarray, np.ndarray]  # around the shape: flat links (fingers, pads) fit a box far better

    @cached_property  # read per gripper sample when the finger table is built
    def corners(self) -> np.ndarray:
        """The box's 8 corners (box_corners' order), each pushed out by BOX_ROUNDING."""
        corners = box_corners(*self.box)
        return corners + np.sign(corners - self.box[0]) * BOX_ROUNDING


_AXES = {"X": np.array([1.0, 0.0, 0.0]), "Y": np.array([0.0, 1.0, 0.0]), "Z": np.array([0.0, 0.0, 1.0])}


def revolute_axis(joint_model) -> np.ndarray | None:
    """The unit axis of a revolute joint in its own frame, or None if it is not one we can read."""
    kind = joint_model.shortname()
    for prefix in ("JointModelRUB", "JointModelR"):
        if kind.startswith(prefix) and kind[len(prefix) :] in _AXES:
            return _AXES[kind[len(prefix) :]]
    if kind in ("JointModelRevoluteUnaligned", "JointModelRevoluteUnboundedUnaligned"):
        axis = np.asarray(joint_model.extract().axis, float)
        return axis / np.linalg.norm(axis)
    return None


def shape_points(geometry) -> np.ndarray:
    """Points whose convex hull is the shape (cylinders and spheres: their capsule's axis)."""
    if isinstance(geometry, coal.Box):
        half = np.asarray(geometry.halfSide)
        return np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
    if isinstance(geometry, coal.ConvexBase):
        return np.asarray(geometry.points())
    if isinstance(geometry, coal.BVHModelBase):
        return np.asarray(geometry.vertices())
    raise TypeError(type(geometry).__name__)


def fit_capsule(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """A capsule containing every point, and so their convex hull: axis along the principal direction, through the
    centre of the smallest circle that holds the points seen along the axis, radius the largest distance from it.
    (Through their mean the axis sits where a mesh's vertices are dense, not in its middle: the UR5e's upper arm
    took 12.2 cm of radius about its mean, 9.0 cm about the circle's centre, and every bound the safety proof
    draws from a capsule is that much looser.)"""
    mean = points.mean(axis=0)
    axis, *normals = np.linalg.svd(points - mean, full_matrices=False)[2]  # the other two span the plane across it
    across_axes = np.array(normals).T
    middle, _ = smallest_circle((points - mean) @ across_axes)
    center = mean + across_axes @ middle
    offsets = points - center
    along = offsets @ axis
    across = np.linalg.norm(offsets - np.outer(along, axis), axis=1)
    radius = float(across.max())  # measured here, not taken from the circle: every point is inside, exactly
    # a point at distance `across` from the axis sits inside the end cap while its
    # projection is within sqrt(r² - across²) of the segment end
    room = np.sqrt(np.maximum(radius**2 - across**2, 0.0))
    low, high = float(np.min(along + room)), float(np.max(along - room))
    if low > high:  # short and round: a sphere does
        middle = center + axis * (low + high) / 2
        radius = float(np.max(np.linalg.norm(points - middle, axis=1)))
        return middle, middle.copy(), radius
    return center + axis * low, center + axis * high, radius


# a point this much (relative) beyond a circle still counts as on it: the capsule is measured around the points anyway
_ON_CIRCLE = 1e-12


def smallest_circle(points: np.ndarray) -> tuple[np.ndarray, float]:
    """The smallest circle holding every 2D point: centre and radius. Only the corners of the points' convex hull
    can lie on it, so Welzl's incremental construction runs on those (a mesh's few hundred vertices seen along an
    axis leave a few dozen), in a fixed shuffled order, on plain floats: per point, numpy's calls would cost more
    than the arithmetic."""
    corners = _hull_corners(points)
    random.Random(0).shuffle(corners)
    (x, y), radius = _circle_holding(corners, len(corners), [])
    return np.array([x, y]), radius


def _hull_corners(points: np.ndarray) -> list[tuple[float, float]]:
    """The corners of the points' 2D convex hull (Andrew's monotone chain); all of them when fewer than three."""
    ordered = sorted(set(map(tuple, points.tolist())))
    if len(ordered) < 3:
        return ordered
    chains: list[list[tuple[float, float]]] = []
    for sweep in (ordered, ordered[::-1]):
        chain: list[tuple[float, float]] = []
        for x, y in sweep:
            # the last corner goes while it does not turn left on the way to this point (cross product written out:
            # a call per test would cost more than the test)
            while (
                len(chain) >= 2
                and (chain[-1][0] - chain[-2][0]) * (y - chain[-2][1])
                - (chain[-1][1] - chain[-2][1]) * (x - chain[-2][0])
                <= 0
            ):
                chain.pop()
            chain.append((x, y))
        chains.append(chain)
    lower, upper = chains
    return lower[:-1] + upper[:-1]


def _circle_holding(points: list, count: int, boundary: list) -> tuple[tuple[float, float], float]:
    """The smallest circle holding points[:count] with every point of `boundary` (at most three) on it."""
    if boundary:
        (cx, cy), radius = _circle_through(boundary)
        k = 0
    else:
        (cx, cy), radius, k = points[0], 0.0, 1
    while k < count:
        x, y = points[k]
        if math.hypot(x - cx, y - cy) > radius * (1 + _ON_CIRCLE) + _ON_CIRCLE:
            if len(boundary) == 2:
                (cx, cy), radius = _circle_through([*boundary, points[k]])
            else:
                (cx, cy), radius = _circle_holding(points, k, [*boundary, points[k]])
        k += 1
    return (cx, cy), radius


def _circle_through(boundary: list) -> tuple[tuple[float, float], float]:
    """The smallest circle with these one to three points on it (three in a line: the widest pair's)."""
    if len(boundary) == 1:
        return boundary[0], 0.0
    if len(boundary) == 2:
        (ax, ay), (bx, by) = boundary
        return ((ax + bx) / 2, (ay + by) / 2), math.hypot(ax - bx, ay - by) / 2
    (ax, ay), (bx, by), (cx, cy) = boundary
    abx, aby, acx, acy = bx - ax, by - ay, cx - ax, cy - ay
    cross = 2.0 * (abx * acy - aby * acx)
    if abs(cross) < 1e-18:
        pairs = [_circle_through([p, q]) for p, q in itertools.combinations(boundary, 2)]
        return max(pairs, key=lambda circle: circle[1])
    ab2, ac2 = abx * abx + aby * aby, acx * acx + acy * acy
    x, y = ax + (acy * ab2 - aby * ac2) / cross, ay + (abx * ac2 - acx * ab2) / cross
    return (x, y), math.hypot(ax - x, ay - y)


def fit_box_frame(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A box containing every point, aligned with their principal directions: its centre, its axes (rows,
    orthonormal) and its half extents along them."""
    center = points.mean(axis=0)
    axes = np.linalg.svd(points - center, full_matrices=False)[2]
    along = (points - center) @ axes.T
    low, high = along.min(axis=0), along.max(axis=0)
    return center + ((low + high) / 2) @ axes, axes, (high - low) / 2


# a nanometre out from the centre along each coordinate: rounding must not shrink a box
BOX_ROUNDING = 1e-9


def box_corners(center: np.ndarray, axes: np.ndarray, half: np.ndarray) -> np.ndarray:
    """The 8 corners of a box, x-, y- and z-steps 4, 2 and 1 apart in the list."""
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    return center + (signs * half) @ axes


def box_of(geometry_object) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The box around a shape (parent joint frame): centre, axes (rows), half extents."""
    geometry, placement = geometry_object.geometry, geometry_object.placement
    if isinstance(geometry, (coal.Cylinder, coal.Capsule, coal.Sphere)):
        radius = float(geometry.radius)
        # half height along the shape's z: a cylinder's half length, a capsule's plus its cap, a sphere's radius
        if isinstance(geometry, coal.Sphere):
            half = radius
        else:
            half = float(geometry.halfLength) + (radius if isinstance(geometry, coal.Capsule) else 0.0)
        local = np.array([[sx * radius, sy * radius, sz * half] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    else:
        local = shape_points(geometry)
    return fit_box_frame(local @ placement.rotation.T + placement.translation)


def capsule_of(geometry_object) -> tuple[np.ndarray, np.ndarray, float]:
    geometry, placement = geometry_object.geometry, geometry_object.placement
    if isinstance(geometry, (coal.Cylinder, coal.Capsule)):
        half = float(geometry.halfLength)
        start, end = placement.act(np.array([0.0, 0.0, -half])), placement.act(np.array([0.0, 0.0, half]))
        return start, end, float(geometry.radius)
    if isinstance(geometry, coal.Sphere):
        center = placement.translation.copy()
        return center, center.copy(), float(geometry.radius)
    local = shape_points(geometry)
    start, end, radius = fit_capsule(local @ placement.rotation.T + placement.translation)
    return start, end, radius * (1 + 1e-9) + 1e-9
