"""Static scene bodies built from primitives: floor, cafe table, pedestal, objects."""

from __future__ import annotations

import numpy as np
import pybullet as p

from envfactory.spec.schema import ObjectSpec, PedestalSpec, TableSpec

TABLE_RGBA = (0.55, 0.42, 0.30, 1.0)
FLOOR_RGBA = (0.85, 0.85, 0.85, 1.0)
MARKER_RGBA = (0.1, 0.8, 0.2, 0.6)


def _box(client: int, half_extents, position, rgba, mass: float = 0.0, orientation=(0.0, 0.0, 0.0, 1.0)) -> int:
    collision = p.createCollisionShape(p.GEOM_BOX, halfExtents=half_extents, physicsClientId=client)
    visual = p.createVisualShape(p.GEOM_BOX, halfExtents=half_extents, rgbaColor=rgba, physicsClientId=client)
    return p.createMultiBody(mass, collision, visual, basePosition=list(position), baseOrientation=list(orientation),
                             physicsClientId=client)


def add_floor(client: int, z: float) -> int:
    return _box(client, [3.0, 3.0, 0.01], [0.0, 0.0, z - 0.01], FLOOR_RGBA)


def add_table(client: int, table: TableSpec) -> list[int]:
    half_x, half_y = table.size[0] / 2, table.size[1] / 2
    top = _box(client, [half_x, half_y, table.thickness / 2],
               [table.center[0], table.center[1], table.top_z - table.thickness / 2], TABLE_RGBA)
    column_height = table.top_z - table.thickness
    column = _box(client, [0.04, 0.04, column_height / 2], [table.center[0], table.center[1], column_height / 2],
                  (0.2, 0.2, 0.2, 1.0))
    return [top, column]


def add_pedestal(client: int, pedestal: PedestalSpec, mount: np.ndarray) -> list[int]:
    half_x, half_y = pedestal.size[0] / 2, pedestal.size[1] / 2
    plate = 0.02
    bodies = [_box(client, [half_x, half_y, plate / 2], [mount[0], mount[1], mount[2] - plate / 2], pedestal.rgba)]
    leg_height = mount[2] - plate
    for sx in (-1, 1):
        for sy in (-1, 1):
            position = [mount[0] + sx * (half_x - 0.02), mount[1] + sy * (half_y - 0.02), leg_height / 2]
            bodies.append(_box(client, [0.02, 0.02, leg_height / 2], position, pedestal.rgba))
    return bodies


def add_object(client: int, spec: ObjectSpec, position, orientation) -> int:
    half = spec.size / 2
    body = _box(client, [half, half, half], position, spec.rgba, mass=spec.mass, orientation=orientation)
    p.changeDynamics(body, -1, lateralFriction=spec.friction, spinningFriction=spec.spinning_friction,
                     rollingFriction=spec.rolling_friction, physicsClientId=client)
    return body


def add_marker(client: int, position, radius: float = 0.025) -> int:
    """A see-through sphere with no collision shape: shows the goal, touches nothing."""
    visual = p.createVisualShape(p.GEOM_SPHERE, radius=radius, rgbaColor=MARKER_RGBA, physicsClientId=client)
    return p.createMultiBody(0.0, -1, visual, basePosition=list(position), physicsClientId=client)
