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
from envfactory.state import PHYSICS_QUANTITIES, PhysicsChange  # noqa: F401  (the protocol's vocabulary)


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
    # True when reset sets the joints directly (a simulator); False when the arm drives
    # home, so the env proves that path clear first
    teleports_on_reset: bool

    def attach_geometry(self, collision) -> None:
        """The env's collision model (its own measuring copy), given once after construction: a simulator
        may play motions the safety check proved clear without dynamics; others ignore it."""

    def reset(self, q_arm: np.ndarray, gripper: float | None, objects: dict[str, tuple[np.ndarray, np.ndarray]]) -> None:
        ...

    def command_joints(self, q_arm_target: np.ndarray, duration: float) -> None:
        ...

    def command_gripper(self, value: float) -> None:
        ...

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
        latency; recorded in info["timing"]); a simulator has nothing to report: {}."""

    def advance(self, seconds: float) -> None:
        """Let `seconds` pass: simulated time in sim, wall time on hardware."""

    def read_joints(self) -> JointReading:
        ...

    def read_object(self, name: str) -> ObjectReading:
        ...

    def mark_goal(self, position: np.ndarray) -> None:
        """Show the goal to people watching (a marker in sim); never part of an observation."""

    def render(self, width: int, height: int) -> np.ndarray:
        ...

    def capture(self, camera: CameraSpec) -> CameraFrame:
        """One frame of a fixed scene camera, for image observation terms."""

    def close(self) -> None:
        ...

