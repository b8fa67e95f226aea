"""When a simulation has left its physics: a joint read far faster than the robot declares it can move, or an
object thrown out of the scene. Such a state is no state of the task (a damping at the top of its bound can
launch a cube to 14 m), so the episode ends there, with the reason, rather than clipping it into an observation
that looks valid and training on it."""

from __future__ import annotations

import math

import numpy as np

from envfactory.backends.base import EpisodeAbort
from envfactory.geometry.frames import TaskFrame
from envfactory.geometry.obstacles import FLOOR_HALF_EXTENT
from envfactory.schema.robot import RobotSpec
from envfactory.step_state import EnvState

# A joint read this many times faster than its declared /joint_states velocity bound: no motor did that.
SPEED_FACTOR = 4.0
# Nothing on a table top moves this fast (a fall from 2 m lands at 6.3 m/s), m/s.
OBJECT_SPEED_LIMIT = 10.0
# An object farther than this above or below the world's origin has left the scene, m.
SCENE_HALF_HEIGHT = 5.0


class SimulationLeftLimits(EpisodeAbort):
    """The simulation read a state no robot or object of the task can be in."""


class SimulationLimits:
    def __init__(self, robot: RobotSpec):
        self.frame = TaskFrame.of(robot)
        self.names = robot.state_names
        self.units = [f"{entry.unit}/s" for entry in robot.joint_states]
        self.speed_limit = SPEED_FACTOR * np.array(
            [max(abs(v) for v in entry.velocity) for entry in robot.joint_states]
        )
        self.breaks = 0  # episodes this env ended for it

    def check(self, state: EnvState) -> None:
        """SimulationLeftLimits naming the first joint or object out of its limits."""
        reason = self._joints(state.joint_velocities) or self._objects(state)
        if reason:
            self.breaks += 1
            raise SimulationLeftLimits(f"the simulation left its limits: {reason}")

    def _joints(self, velocities: np.ndarray) -> str:
        speeds = np.abs(np.asarray(velocities, float))
        within = speeds <= self.speed_limit  # NaN counts as over
        if within.all():
            return ""
        over = np.flatnonzero(~within)
        index = int(over[np.argmax(speeds[over] / self.speed_limit[over])])
        return (
            f"joint {self.names[index]} reads {speeds[index]:.3g} {self.units[index]}, over {SPEED_FACTOR:g} times its "
            f"declared velocity bound ({self.speed_limit[index] / SPEED_FACTOR:g} {self.units[index]})"
        )

    def _objects(self, state: EnvState) -> str:
        # in plain floats: this runs at every step, and numpy's calls on three numbers cost more than the arithmetic
        for name, body in state.objects.items():
            world = self.frame.to_world(body.position)
            x, y, z = world.tolist()
            speed = math.hypot(*body.linear_velocity.tolist())
            # past the floor's edge it falls for ever; its observation box ends there too (geometry/point_boxes.py);
            # a NaN fails every comparison, so it counts as out
            if not (abs(x) <= FLOOR_HALF_EXTENT and abs(y) <= FLOOR_HALF_EXTENT and abs(z) <= SCENE_HALF_HEIGHT):
                return (
                    f"object {name} is at {np.round(world, 2).tolist()} m (world frame), out of the scene: off the "
                    f"floor, which ends {FLOOR_HALF_EXTENT:g} m either side of the origin"
                )
            if not speed <= OBJECT_SPEED_LIMIT:
                return f"object {name} moves at {speed:.3g} m/s, thrown (limit {OBJECT_SPEED_LIMIT:g} m/s)"
        return ""
