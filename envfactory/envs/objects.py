"""The task's objects at run time: where they spawn, and their state from pose readings.

Velocities are finite differences over the step between two pose readings,
which the real robot's pose topic supports as well as the simulator does.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from envfactory.backends.base import ObjectReading
from envfactory.geometry.frames import TaskFrame
from envfactory.geometry.kinematics import quaternion_to_matrix
from envfactory.geometry.obstacles import table_bounds_xy
from envfactory.schema.models import ObjectSpec, TableSpec
from envfactory.step_state import ObjectState

IDENTITY_QUATERNION = np.array([0.0, 0.0, 0.0, 1.0])


class ObjectSpawner:
    """Spawn poses in the task frame: the declared position, or a random offset from it kept on the table."""

    def __init__(self, objects: dict[str, ObjectSpec], table: TableSpec, frame: TaskFrame):
        self.objects = objects
        self.frame = frame
        # in a task frame turned about z, spawns are kept on the table in the world, where it is a box
        self.table_min, self.table_max = table_bounds_xy(table, TaskFrame(np.zeros(3)) if frame.rotated else frame)

    def sample(self, rng: np.random.Generator) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        poses = {}
        for name, spec in self.objects.items():
            position = np.array(spec.spawn.position, dtype=float)
            if spec.spawn.random:
                offset = np.asarray(spec.spawn.offset)
                position[:2] += rng.uniform(-offset, offset)
                half = spec.half_extents[0]
                if not self.frame.rotated:
                    position[:2] = np.clip(position[:2], self.table_min + half, self.table_max - half)
                else:  # the cube's footprint, turned with the frame, stays inside the table
                    world = self.frame.to_world(position)
                    corner = np.abs(self.frame.rotation[:2, :2]) @ np.array([half, half])
                    world[:2] = np.clip(world[:2], self.table_min + corner, self.table_max - corner)
                    position = self.frame.to_task(world)
            poses[name] = (position, IDENTITY_QUATERNION.copy())
        return poses


class ObjectTracker:
    """Turns successive pose readings of one object into its full state."""

    def __init__(self):
        self._previous: tuple[ObjectReading, ObjectState] | None = None  # the last reading and the state made of it

    def reset(self) -> None:
        self._previous = None

    def update(self, reading: ObjectReading) -> ObjectState:
        previous = self._previous
        joint = 0.0 if reading.joint is None else float(reading.joint)
        if previous is not None and _same_pose(reading, previous[0]):
            # an object at rest (most steps): its rotation and angles stand, and it did not move
            state = previous[1]
            self._previous = (reading, state)
            return ObjectState(reading.position, state.rotation, state.rpy, np.zeros(3), np.zeros(3), joint)
        rotation = quaternion_to_matrix(reading.quaternion)
        linear, angular, joint_velocity = np.zeros(3), np.zeros(3), 0.0
        if previous is not None and reading.stamp > previous[0].stamp:
            dt = reading.stamp - previous[0].stamp
            linear = (reading.position - previous[0].position) / dt
            angular = pin.log3(rotation @ previous[1].rotation.T) / dt
            joint_velocity = (joint - previous[1].joint) / dt
        state = ObjectState(
            reading.position, rotation, pin.rpy.matrixToRpy(rotation), linear, angular, joint, joint_velocity
        )
        self._previous = (reading, state)
        return state


def _same_pose(a: ObjectReading, b: ObjectReading) -> bool:
    return a.position.tolist() == b.position.tolist() and a.quaternion.tolist() == b.quaternion.tolist()
