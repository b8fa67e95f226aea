"""Scene bodies built from primitives: the fixed obstacles, the task's objects, the goal marker."""

from __future__ import annotations

import pybullet as p

from envfactory.backends.view import MARKER_RGBA
from envfactory.geometry.obstacles import Obstacle
from envfactory.schema.models import ObjectSpec


def _box(client: int, half_extents, position, rgba, mass: float = 0.0, orientation=(0.0, 0.0, 0.0, 1.0)) -> int:
    collision = p.createCollisionShape(p.GEOM_BOX, halfExtents=half_extents, physicsClientId=client)
    visual = p.createVisualShape(p.GEOM_BOX, halfExtents=half_extents, rgbaColor=rgba, physicsClientId=client)
    return p.createMultiBody(
        mass, collision, visual, basePosition=list(position), baseOrientation=list(orientation), physicsClientId=client
    )


def add_obstacles(client: int, obstacles: list[Obstacle]) -> list[int]:
    return [_box(client, list(o.half_extents), list(o.center), o.rgba) for o in obstacles]


def add_object(client: int, spec: ObjectSpec, position, orientation) -> int:
    half = spec.size / 2
    body = _box(client, [half, half, half], position, spec.rgba, mass=spec.mass, orientation=orientation)
    p.changeDynamics(
        body,
        -1,
        lateralFriction=spec.friction,
        spinningFriction=spec.spinning_friction,
        rollingFriction=spec.rolling_friction,
        physicsClientId=client,
    )
    return body


def add_marker(client: int, position, radius: float = 0.025) -> int:
    """A see-through sphere with no collision shape: shows the goal, touches nothing."""
    visual = p.createVisualShape(p.GEOM_SPHERE, radius=radius, rgbaColor=MARKER_RGBA, physicsClientId=client)
    return p.createMultiBody(0.0, -1, visual, basePosition=list(position), physicsClientId=client)
