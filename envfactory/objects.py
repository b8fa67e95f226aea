"""The task's objects at run time: where they spawn, and their state from pose readings.

Velocities are finite differences over the step between two pose readings,
which the real robot's pose topic supports as well as the simulator does.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from envfactory.backends.base import ObjectReading
from envfactory.kinematics import quaternion_to_matrix
from envfactory.spec.schema import ObjectSpec
from envfactory.state import ObjectState

IDENTITY_QUATERNION = np.array([0.0, 0.0, 0.0, 1.0])


class ObjectSpawner:
    """Spawn poses in the task frame: the declared position, or a random offset from it kept on the table."""

    def __init__(self, objects: dict[str, ObjectSpec], table_xy: tuple[np.ndarray, np.ndarray]):
        self.objects = objects
        self.table_min, self.table_max = table_xy

    def sample(self, rng: np.random.Generator) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        poses = {}
        for name, spec in self.objects.items():
            position = np.array(spec.spawn.position, dtype=float)
            if spec.spawn.random:
                offset = np.asarray(spec.spawn.offset)
                position[:2] += rng.uniform(-offset, offset)
                half = spec.size / 2
                position[:2] = np.clip(position[:2], self.table_min + half, self.table_max - half)
            poses[name] = (position, IDENTITY_QUATERNION.copy())
        return poses


class ObjectTracker:
    """Turns successive pose readings of one object into its full state."""

    def __init__(self):
        self._previous: tuple[ObjectReading, np.ndarray] | None = None  # the last reading and its rotation

    def reset(self) -> None:
        self._previous = None

    def update(self, reading: ObjectReading) -> ObjectState:
        rotation = quaternion_to_matrix(reading.quaternion)
        previous, self._previous = self._previous, (reading, rotation)
        linear, angular = np.zeros(3), np.zeros(3)
        if previous is not None and reading.stamp > previous[0].stamp:
            dt = reading.stamp - previous[0].stamp
            linear = (reading.position - previous[0].position) / dt
            angular = pin.log3(rotation @ previous[1].T) / dt
        return ObjectState(reading.position, rotation, pin.rpy.matrixToRpy(rotation), linear, angular)
