"""The Backend protocol: what an env needs from a simulator or a real robot.

Positions are in the task frame; joint vectors are in /joint_states order.
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from envfactory.schema.models import CameraSpec
from envfactory.step_state import PHYSICS_QUANTITIES, PhysicsChange  # noqa: F401  (the protocol's vocabulary)


def window_impossible() -> bool:
    """Whether a window cannot open here: Linux without an X display (PyBullet's GUI then ends the whole
    process from inside its C code, so the check must come before it is asked)."""
    return sys.platform.startswith("linux") and not os.environ.get("DISPLAY")


@dataclass(frozen=True)
class JointReading:
    position: np.ndarray
    velocity: np.ndarray
    stamp: float  # seconds: simulated time in sim, local receive time on hardware


@dataclass(frozen=True)
class ObjectReading:
    position: np.ndarray
    quaternion: np.ndarray  # x, y, z, w
    stamp: float
    joint: float | None = None  # a fixture's joint, past its lower limit (m); None for a free object


@dataclass(frozen=True)
class CameraFrame:
    rgb: np.ndarray  # (height, width, 3) uint8
    depth: np.ndarray  # (height, width) float32, metres along the view axis


class BackendError(RuntimeError):
    """The backend cannot go on: the arm is stopped and the step fails."""


class EpisodeAbort(BackendError):
    """This episode cannot safely go on: nothing more is commanded, the arm is
    stopped, and the env ends the episode with the reason."""


class StaleFeed(EpisodeAbort):
    """A reading (joint states, an object pose) is older than its limit or never came."""


class MalformedFeed(EpisodeAbort):
    """A reading arrived that does not have the shape or values its type promises."""


class CommandIgnored(EpisodeAbort):
    """The arm did not start following a command it should follow: nothing executes it."""


class ConnectionLost(BackendError):
    """The connection to the robot is gone; reset() reconnects, within bounds."""


class CommandRefused(BackendError):
    """A command topic that nothing of the expected type subscribes to: refused before any motion."""


class DriverRefused(BackendError):
    """The driver refused a setup call (its timing, a mode): the env stops rather than run on another timing."""


class MotionRefused(BackendError):
    """The real-robot motion gate is closed."""


class Backend(Protocol):
    """What an env needs from a simulator or a real robot; every backend, built in or joined through the
    `envfactory.backends` entry points, keeps this contract.

    Units: joint values in rad (m for a prismatic finger), in /joint_states order where a whole state vector
    goes in or out, in action order (the robot's arm_joints) where only the arm does; positions in m in the
    task frame; quaternions x, y, z, w; times in s. A call that moves the arm is checked by the env's safety
    proof before it reaches the backend: a backend plays what it is given, along the joint-space line from
    where the arm is, all joints arriving together. Every failure is a BackendError; an EpisodeAbort subclass
    means the arm was stopped and this episode cannot go on, the env ends it with the reason."""

    # A simulator is also given `fixtures=` (name -> envfactory.geometry.fixtures.FixtureModel) when the task
    # stands fixtures: it loads each one's URDF where the model stands it, closes its joint at every reset, and
    # reads it through read_object. The compiler refuses fixtures on every other backend.

    # True when reset sets the joints directly (a simulator); False when the arm drives
    # home, so the env proves that path clear first
    teleports_on_reset: bool

    def attach_geometry(self, collision) -> None:
        """The env's collision model (its own measuring copy), given once after construction: a simulator
        may play motions the safety check proved clear without dynamics; others ignore it."""

    def reset(
        self, q_arm: np.ndarray, gripper: float | None, objects: dict[str, tuple[np.ndarray, np.ndarray]]
    ) -> None:
        """Put the arm at `q_arm` (action order) and the gripper at `gripper` (None: leave it as it is), and each
        named object at its (position, quaternion). Blocks until done: a simulator sets the state at once; a
        real arm drives home at its reset speed, and its objects stay where people put them."""

    def command_joints(self, q_arm_target: np.ndarray, duration: float) -> None:
        """Send the arm towards `q_arm_target` (action order), the motion to take `duration` s (longer where a
        joint's speed limit needs it). Returns at once: the motion happens over the following advance()."""

    def command_gripper(self, value: float) -> None:
        """Send the gripper's driven joint towards `value` (its joint units). Returns at once; the finger drive
        runs at the gripper's max_velocity over the following advance() and, in simulation, beyond it."""

    def recover(self) -> None:
        """Make the backend usable again after any fault (reconnect, clear the fault, wait for
        fresh readings), or raise saying why not. First thing in every reset."""

    def stop(self) -> None:
        """Hold the arm where it is. Always allowed: stopping is not motion."""

    def apply_physics(self, change: PhysicsChange) -> None:
        """Set one randomized physical quantity (events, envfactory/terms/events.py): simulators only; the
        compiler refuses randomization on other backends."""

    def step_timing(self) -> dict[str, float]:
        """How this step's readings and commands were timed on a real path (reading age, repeats, command
        latency, motion and step time; recorded in info["timing"]); a simulator has nothing to report: {}."""

    def advance(self, seconds: float) -> None:
        """The step's cycle, `seconds` long. Blocks until it is over and the commanded motion is done: a
        simulator plays `seconds` of simulated time (a motion of `duration` <= `seconds` ends inside it); a
        real arm waits at least `seconds` of wall time from the step's first command and until the arm is at
        its target, or stops the arm and raises an EpisodeAbort saying why. The step's observation is read
        after it."""

    def read_joints(self) -> JointReading:
        """The newest joint state, in /joint_states order, as the robot's driver publishes it. Does not
        block; on a real path a reading older than its limit raises StaleFeed."""

    def read_object(self, name: str) -> ObjectReading:
        """The newest pose of a task object, in the task frame; of a fixture (task.fixtures), its moving link's pose
        and its joint's value past the lower limit. Does not block; stale raises StaleFeed."""

    def mark_goal(self, position: np.ndarray) -> None:
        """Show the goal to people watching (a marker in sim); never part of an observation."""

    def render(self, width: int, height: int) -> np.ndarray:
        """An RGB picture of the scene, (height, width, 3) uint8, for people and videos; a real arm has none and
        raises BackendError."""

    def capture(self, camera: CameraSpec) -> CameraFrame:
        """One frame of a fixed scene camera, for image observation terms."""

    def close(self) -> None:
        """Release the engine or the connection; a real arm is stopped first. Safe to call twice."""
