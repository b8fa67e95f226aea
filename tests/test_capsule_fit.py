"""The capsules the safety proof bounds each robot shape with: the smallest circle they are centred on, against a
search over every pair and triple of points; and every shipped robot's capsules against the points they must hold
(coal's exact clearances judge the bounds drawn from them in test_safety.py)."""

from __future__ import annotations

import itertools

import coal
import numpy as np
import pytest

import envfactory
from envfactory.envs import RobotEnv
from envfactory.geometry.collision.shapes import fit_capsule, shape_points, smallest_circle


def _smallest_by_search(points: np.ndarray) -> float:
    """The smallest circle's radius by trying every circle on two points as a diameter and through three."""
    best = np.inf
    candidates = []
    for a, b in itertools.combinations(points, 2):
        candidates.append((a + b) / 2)
    for a, b, c in itertools.combinations(points, 3):
        ab, ac = b - a, c - a
        cross = 2.0 * (ab[0] * ac[1] - ab[1] * ac[0])
        if abs(cross) > 1e-12:
            candidates.append(
                a + np.array([ac[1] * (ab @ ab) - ab[1] * (ac @ ac), ab[0] * (ac @ ac) - ac[0] * (ab @ ab)]) / cross
            )
    for center in candidates:
        best = min(best, float(np.max(np.linalg.norm(points - center, axis=1))))
    return best


def test_the_smallest_circle_is_the_smallest_of_every_candidate_circle():
    """Random clouds of 2 to 12 points, some with repeated points, some on a line: the circle holds every point
    and is as small as the best circle on two or three of them (which is where the smallest one always lies)."""
    rng = np.random.default_rng(4)
    for trial in range(300):
        points = rng.normal(size=(int(rng.integers(2, 13)), 2)) * rng.uniform(0.01, 1.0)
        if trial % 5 == 1:
            points[-1] = points[0]  # a repeated point
        if trial % 5 == 2:
            points = np.outer(rng.uniform(-1, 1, len(points)), rng.normal(size=2))  # all on a line
        center, radius = smallest_circle(points)
        assert np.all(np.linalg.norm(points - center, axis=1) <= radius * (1 + 1e-9) + 1e-12)
        assert radius == pytest.approx(_smallest_by_search(points), rel=1e-9, abs=1e-12)


def test_one_point_is_its_own_circle():
    center, radius = smallest_circle(np.array([[0.3, -0.2]]))
    assert np.array_equal(center, [0.3, -0.2]) and radius == 0.0


def _mean_axis_radius(points: np.ndarray) -> float:
    """The radius about the principal axis through the points' mean (the fit before the circle's centre)."""
    offsets = points - points.mean(axis=0)
    axis = np.linalg.svd(offsets, full_matrices=False)[2][0]
    return float(np.linalg.norm(offsets - np.outer(offsets @ axis, axis), axis=1).max())


def _segment_gaps(points, start, end):
    way = end - start
    share = np.clip((points - start) @ way / max(way @ way, 1e-300), 0.0, 1.0)
    return np.linalg.norm(points - (start + np.outer(share, way)), axis=1)


@pytest.mark.parametrize(
    "env_id", ["UR5eReacherSim-v0", "VX300SReacherSim-v0", "PandaReachSim-v0", "NED2ReacherSim-v0"]
)
def test_every_robot_capsule_holds_its_shape_and_is_no_wider_than_about_the_mean(env_id):
    env = RobotEnv(envfactory.blueprint(env_id))
    try:
        widths = {}
        for geometry_object in env.safety.collision.geometry.geometryObjects:
            geometry, placement = geometry_object.geometry, geometry_object.placement
            if geometry_object.name.startswith("obstacle") or isinstance(
                geometry, (coal.Cylinder, coal.Capsule, coal.Sphere)
            ):
                continue
            points = shape_points(geometry) @ placement.rotation.T + placement.translation
            start, end, radius = fit_capsule(points)
            assert np.all(_segment_gaps(points, start, end) <= radius * (1 + 1e-12) + 1e-12), geometry_object.name
            assert radius <= _mean_axis_radius(points) + 1e-12, geometry_object.name
            widths[geometry_object.name] = (radius, _mean_axis_radius(points))
        if env_id.startswith("UR5e"):  # the meshes whose vertices crowd at one end: the fit's reason to be
            radius, about_mean = widths["upper_arm_link_0"]
            assert radius < 0.091 and about_mean > 0.12, widths["upper_arm_link_0"]
    finally:
        env.close()
