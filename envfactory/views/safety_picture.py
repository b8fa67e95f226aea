"""A picture of what the safety check protects: the arm in its scene, each link tinted by its clearance."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pybullet as p

from envfactory.backends.pybullet.backend import PyBulletBackend
from envfactory.geometry.frames import TaskFrame
from envfactory.geometry.robot_model import robot_geometry

NEAR, CLOSE, CLEAR = (0.9, 0.1, 0.1, 1.0), (0.95, 0.75, 0.1, 1.0), (0.2, 0.75, 0.3, 1.0)


def link_clearances(compiled, q_arm, gripper: float) -> dict[str, float]:
    """The lowest clearance of each link's shapes, from the scene and the arm's other links."""
    collision = robot_geometry(compiled.spec, compiled.asset_root, compiled.fixture_folders).collision.measuring_copy()
    collision.pose(np.asarray(q_arm, float), gripper)
    clearance = collision.all_exact()
    lowest: dict[str, float] = {}
    for pair, value in enumerate(clearance):
        for link in collision.pair_names(pair):
            if link in collision.links:
                lowest[link] = min(lowest.get(link, np.inf), float(value))
    return lowest


def render_clearance(compiled, out: Path, q_arm=None, width: int = 800, height: int = 600) -> float:
    """Write a PNG of the arm at q_arm (home by default), links red within the margin, amber within three
    margins, green beyond; return the lowest clearance."""
    import imageio

    spec = compiled.spec
    robot = spec.robot
    q_arm = np.asarray(robot.home if q_arm is None else q_arm, float)
    if q_arm.shape != (len(robot.arm_joints),):
        raise ValueError(f"give {len(robot.arm_joints)} joint values, got {q_arm.size}")
    gripper = spec.gripper_assumed_at_reset
    margin = spec.env.safety.surface_margin
    lowest = link_clearances(compiled, q_arm, gripper)
    backend = PyBulletBackend(
        spec, robot_geometry(spec, compiled.asset_root, compiled.fixture_folders).urdf, TaskFrame.of(robot)
    )
    try:
        backend.reset(q_arm, gripper, {})
        client, body = backend.client, backend.body
        names = {
            p.getJointInfo(body, j, physicsClientId=client)[12].decode(): j
            for j in range(p.getNumJoints(body, physicsClientId=client))
        }
        names[p.getBodyInfo(body, physicsClientId=client)[0].decode()] = -1
        for link, clearance in lowest.items():
            colour = NEAR if clearance < margin else CLOSE if clearance < 3 * margin else CLEAR
            p.changeVisualShape(body, names.get(link, -1), rgbaColor=colour, physicsClientId=client)
        image = backend.render(width, height)
    finally:
        backend.close()
    imageio.imwrite(out, image)
    return min(lowest.values())
