"""The fixed obstacles of the scene: floor, table, pedestal and any declared box.

One list serves the simulator, which builds its bodies from it, and the
safety check, which keeps every link clear of it: the arm is guarded against
exactly the scene it moves in.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from envfactory.schema.models import ComposedSpec, TableSpec

FLOOR_HALF_EXTENT = 3.0  # m: beyond every arm's reach
FLOOR_THICKNESS = 0.02
TABLE_COLUMN_HALF_WIDTH = 0.04
PEDESTAL_PLATE = 0.02
PEDESTAL_LEG_HALF_WIDTH = 0.02

TABLE_RGBA = (0.55, 0.42, 0.30, 1.0)
TABLE_TOP = "table top"  # the obstacle objects rest on
FLOOR = "floor"  # the obstacle under everything
COLUMN_RGBA = (0.2, 0.2, 0.2, 1.0)
FLOOR_RGBA = (0.85, 0.85, 0.85, 1.0)
# lateral, spinning, rolling friction of the table, obstacles and robot links: PyBullet's default, which both
# engines give every surface a spec gives no friction
SURFACE_FRICTION = (0.5, 0.0, 0.0)


@dataclass(frozen=True)
class Obstacle:
    """An axis-aligned box in the world frame: fixed, or part of a fixture that rides on its joint."""

    name: str
    center: tuple[float, float, float]
    half_extents: tuple[float, float, float]
    rgba: tuple[float, float, float, float] = (0.5, 0.5, 0.5, 1.0)
    fixture: str = ""  # the fixture it is part of (task.fixtures), if any
    moves: bool = False  # it rides on its fixture's joint: the joint's reading moves it before each check
    travel: tuple[float, float, float] = (0.0, 0.0, 0.0)  # m of world displacement per unit of the joint's value
    # how far the gripper's fingers may be commanded into it (a drawer's handle, which they close on), m; 0: they
    # keep the surface margin from it, as every other shape of the arm always does
    touch_depth: float = 0.0

    @property
    def low(self) -> np.ndarray:
        return np.subtract(self.center, self.half_extents)

    @property
    def high(self) -> np.ndarray:
        return np.add(self.center, self.half_extents)

    def widened(self, margin_xy: float) -> "Obstacle":
        """The same box grown sideways: room for a table placed a little off its nominal spot."""
        x, y, z = self.half_extents
        return replace(self, half_extents=(x + margin_xy, y + margin_xy, z))


def table_obstacles(table: TableSpec) -> list[Obstacle]:
    x, y = table.center
    half_x, half_y = table.size[0] / 2, table.size[1] / 2
    column_height = table.top_z - table.thickness
    return [
        Obstacle(
            TABLE_TOP, (x, y, table.top_z - table.thickness / 2), (half_x, half_y, table.thickness / 2), TABLE_RGBA
        ),
        Obstacle(
            "table column",
            (x, y, column_height / 2),
            (TABLE_COLUMN_HALF_WIDTH, TABLE_COLUMN_HALF_WIDTH, column_height / 2),
            COLUMN_RGBA,
        ),
    ]


def scene_obstacles(spec: ComposedSpec) -> list[Obstacle]:
    """Every fixed body of the scene, world frame, in a stable order."""
    floor_z = spec.env.safety.floor_z
    obstacles = [
        Obstacle(
            FLOOR,
            (0.0, 0.0, floor_z - FLOOR_THICKNESS / 2),
            (FLOOR_HALF_EXTENT, FLOOR_HALF_EXTENT, FLOOR_THICKNESS / 2),
            FLOOR_RGBA,
        )
    ]
    obstacles += table_obstacles(spec.scene.table)
    robot = spec.robot
    if robot.pedestal is not None:
        mount, pedestal = robot.mount, robot.pedestal
        half_x, half_y = pedestal.size[0] / 2, pedestal.size[1] / 2
        obstacles.append(
            Obstacle(
                "pedestal plate",
                (mount[0], mount[1], mount[2] - PEDESTAL_PLATE / 2),
                (half_x, half_y, PEDESTAL_PLATE / 2),
                pedestal.rgba,
            )
        )
        leg_height = mount[2] - PEDESTAL_PLATE - floor_z
        for sx in (-1, 1):
            for sy in (-1, 1):
                center = (
                    mount[0] + sx * (half_x - PEDESTAL_LEG_HALF_WIDTH),
                    mount[1] + sy * (half_y - PEDESTAL_LEG_HALF_WIDTH),
                    floor_z + leg_height / 2,
                )
                obstacles.append(
                    Obstacle(
                        f"pedestal leg {'-+'[sx > 0]}x{'-+'[sy > 0]}y",
                        center,
                        (PEDESTAL_LEG_HALF_WIDTH, PEDESTAL_LEG_HALF_WIDTH, leg_height / 2),
                        pedestal.rgba,
                    )
                )
    for name, box in spec.scene.obstacles.items():
        obstacles.append(Obstacle(name, tuple(box.center), tuple(s / 2 for s in box.size), tuple(box.rgba)))
    return obstacles


def guarded_obstacles(spec: ComposedSpec) -> list[Obstacle]:
    """The obstacles the safety check keeps the arm clear of: the scene's, with the table top widened by
    the spec's footprint margin."""
    widened = spec.env.safety.table_footprint_margin
    return [o.widened(widened) if o.name == TABLE_TOP else o for o in scene_obstacles(spec)]


def table_bounds_xy(table: TableSpec, frame) -> tuple[np.ndarray, np.ndarray]:
    """The table top's footprint in the task frame (an envfactory.geometry.frames.TaskFrame): (min xy, max xy);
    in a frame turned about z, the box around the turned footprint."""
    if frame.rotated:
        corners = frame.table_corners(table)
        return corners.min(axis=0), corners.max(axis=0)
    half = np.asarray(table.size) / 2.0
    center = np.asarray(table.center) - frame.origin[:2]
    return center - half, center + half
