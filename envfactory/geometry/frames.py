"""Where the task frame and the robot base sit in the world.

The task frame is the world, or the robot base: its position `mount` and its
orientation `mount_rpy`. Goals, spawns and observations are task-frame values;
PyBullet and the scene's obstacles are world values. The Pinocchio model is
built with the base's rotation in it (its frame is the world's axes at the
base's origin), so every link pose, and the collision geometry riding on
them, already carries the base orientation.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin


def base_rotation(robot) -> np.ndarray:
    """The robot base's orientation in the world (rotation matrix)."""
    return pin.rpy.rpyToMatrix(*(float(a) for a in robot.mount_rpy))


def place_base(model, rotation: np.ndarray) -> None:
    """Turn a fixed-base Pinocchio model about its origin: every joint and frame hanging on the
    universe moves with the base. Geometry built from the model afterwards follows."""
    if np.array_equal(rotation, np.eye(3)):
        return
    base = pin.SE3(rotation, np.zeros(3))
    for joint in range(1, model.njoints):
        if model.parents[joint] == 0:
            model.jointPlacements[joint] = base * model.jointPlacements[joint]
    for frame in model.frames:
        if frame.parentJoint == 0 and frame.name != "universe":
            frame.placement = base * frame.placement


class TaskFrame:
    """The task frame's pose in the world; an unrotated frame is a bare translation, so the
    numbers of the shipped robots are exactly those of a subtraction."""

    def __init__(self, origin, rotation: np.ndarray | None = None):
        self.origin = np.asarray(origin, float)
        self.rotation = np.eye(3) if rotation is None else np.asarray(rotation, float)
        self.rotated = not np.array_equal(self.rotation, np.eye(3))
        self._quaternion = pin.Quaternion(self.rotation)

    @classmethod
    def of(cls, robot) -> "TaskFrame":
        if robot.task_frame == "world":
            return cls(np.zeros(3))
        return cls(robot.mount, base_rotation(robot))

    def to_world(self, point) -> np.ndarray:
        point = np.asarray(point, float)
        return self.origin + (point @ self.rotation.T if self.rotated else point)

    def to_task(self, point) -> np.ndarray:
        offset = np.asarray(point, float) - self.origin
        return offset @ self.rotation if self.rotated else offset

    def quaternion_to_world(self, quaternion) -> np.ndarray:
        """An (x, y, z, w) orientation given in the task frame, in the world."""
        if not self.rotated:
            return np.asarray(quaternion, float)
        x, y, z, w = quaternion
        return (self._quaternion * pin.Quaternion(w, x, y, z)).coeffs().copy()

    def quaternion_to_task(self, quaternion) -> np.ndarray:
        if not self.rotated:
            return np.asarray(quaternion, float)
        x, y, z, w = quaternion
        return (self._quaternion.conjugate() * pin.Quaternion(w, x, y, z)).coeffs().copy()

    def base_in_task(self, robot) -> pin.SE3:
        """Where the Pinocchio model's frame (the world's axes at the base origin) sits in the task frame."""
        return pin.SE3(self.rotation.T, self.to_task(robot.mount))

    def table_corners(self, table) -> np.ndarray:
        """The table top's four corners (x, y) in the task frame."""
        half = np.asarray(table.size, float) / 2
        corners = [
            [table.center[0] + sx * half[0], table.center[1] + sy * half[1], table.top_z]
            for sx in (-1, 1)
            for sy in (-1, 1)
        ]
        return np.array([self.to_task(c)[:2] for c in corners])


def nearest_top_down(
    down: np.ndarray, current: np.ndarray, closing_axis: int, yaw: float | None = None, period: float = np.pi
) -> np.ndarray:
    """The top-down orientation (`down` turned about the vertical) whose finger-closing axis, seen from above,
    lies at `yaw` modulo `period` (the fingers are symmetric: a half turn grips alike; a box's faces: a
    quarter turn), turned as little as possible from `current`; with no `yaw`, where `current` has it now.
    Read from the closing axis itself, so it means the same whether or not the gripper points down yet."""
    base = float(np.arctan2(down[1, closing_axis], down[0, closing_axis]))
    axis = current[:2, closing_axis]
    now = float(np.arctan2(axis[1], axis[0])) - base if np.linalg.norm(axis) > 1e-6 else 0.0
    wanted = now if yaw is None else yaw - base
    wanted = now + (wanted - now + period / 2) % period - period / 2
    return pin.rpy.rpyToMatrix(0.0, 0.0, wanted) @ down
