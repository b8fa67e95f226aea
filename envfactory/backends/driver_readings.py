"""Joint readings as the robot's real driver publishes them, for a simulator: what the driver derives rather than
measures (an Interbotix gripper's horn angle, from its finger through the linkage) and what it reports as zero
(xs_sdk's finger velocities). A policy trained in simulation then reads, column for column, what it will read
on the real arm."""

from __future__ import annotations

import math

import numpy as np

from envfactory.schema.models import RobotSpec


def horn_angle(finger: float, radius: float, arm: float) -> float:
    """The horn's angle for a finger at `finger` (half the distance between the fingers)."""
    cosine = (radius * radius + finger * finger - arm * arm) / (2.0 * radius * finger) if finger else 1.0
    return math.pi / 2 - math.acos(min(max(cosine, -1.0), 1.0))


def horn_rate(finger: float, finger_rate: float, radius: float, arm: float) -> float:
    """d(angle)/dt for a finger moving at `finger_rate` (the chain rule through the linkage)."""
    if not finger:
        return 0.0
    cosine = (radius * radius + finger * finger - arm * arm) / (2.0 * radius * finger)
    if abs(cosine) >= 1.0:
        return 0.0
    d_cosine = (finger * finger - radius * radius + arm * arm) / (2.0 * radius * finger * finger)
    return d_cosine / math.sqrt(1.0 - cosine * cosine) * finger_rate


class DriverReadings:
    def __init__(self, robot: RobotSpec):
        urdf_names = [entry.urdf_joint for entry in robot.joint_states]
        self.horns = [
            (index, urdf_names.index(entry.horn.finger), entry.horn.radius, entry.horn.arm)
            for index, entry in enumerate(robot.joint_states)
            if entry.horn is not None
        ]
        self.still = np.array(
            [index for index, entry in enumerate(robot.joint_states) if not entry.reports_velocity], dtype=int
        )

    def __bool__(self) -> bool:
        return bool(self.horns) or bool(self.still.size)

    def apply(self, position: np.ndarray, velocity: np.ndarray) -> None:
        """Turn a simulator's readings (in /joint_states order) into the driver's, in place."""
        for index, finger, radius, arm in self.horns:
            position[index] = horn_angle(float(position[finger]), radius, arm)
            velocity[index] = horn_rate(float(position[finger]), float(velocity[finger]), radius, arm)
        velocity[self.still] = 0.0
