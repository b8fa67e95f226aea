"""Env settings (the seeds' kwargs land here), the scene, the workspace and the registration block."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field, field_validator, model_validator

from envfactory.spec.base import Model, Vec3, located, ordered
from envfactory.spec.numbers import NonNegative, Positive, Real

# Largest joint change one action may command: a full turn (no revolute joint can travel further).
MAX_JOINT_DELTA_LIMIT = 6.2832  # 2π
# A registration entry beyond this many steps per episode is a typo, not a task.
MAX_EPISODE_STEPS_LIMIT = 1_000_000


class ActionSettings(Model):
    ee: bool = False
    delta: bool = True
    # The action box times delta_coeff is the step: above 1 the step outgrows the box.
    delta_coeff: Positive = Field(default=0.05, le=1.0)


class TimingSettings(Model):
    loop_rate: Positive = 10.0
    action_cycle_time: Positive = 0.5
    action_speed: Positive = 0.2
    realtime: bool = False

    @model_validator(mode="after")
    def _cycle_covers_loop(self) -> "TimingSettings":
        if self.action_cycle_time < 1.0 / self.loop_rate - 1e-9:
            raise located(
                "action_cycle_time", f"action_cycle_time ({self.action_cycle_time}) must be >= 1 / loop_rate ({1.0 / self.loop_rate:g})"
            )
        return self


class SafetySettings(Model):
    floor_z: Real = 0.0
    surface_margin: NonNegative = 0.015
    table_footprint_margin: NonNegative = 0.03
    max_joint_delta: Positive = Field(default=0.5, le=MAX_JOINT_DELTA_LIMIT)


class RealSettings(Model):
    """The real robot over rosbridge: connection, gates and limits. Sim ignores these."""

    host: str = "localhost"
    port: int = Field(default=9090, ge=1, le=65535)
    allow_motion: bool = False  # allow_real_robot_motion; ALLOW_REAL_ROBOT_MOTION=1 also allows
    connect_timeout_s: Positive = 5.0
    reconnect_tries: int = Field(default=3, ge=0, le=100)  # bounded, with exponential backoff
    joint_state_timeout_s: Positive = 0.5
    cube_pose_timeout_s: Positive = 1.0
    deadman_s: Positive = 1.5  # no command for this long: the arm is stopped
    reset_speed: Positive = 0.3  # rad/s of the slowest-allowed move home at reset
    reset_timeout_s: Positive = 30.0
    reset_tolerance: Positive = 0.02  # rad: home counts as reached
    auto_launch_cube_tracker: bool = False  # True is refused: the user starts the tracker
    cube_tracker_camera: Literal["kinect2", "zed2", "d405"] = "kinect2"
    cube_tracker_target_frame: str = ""  # if set, object poses must be given in (or transform to) this frame


class EnvSettings(Model):
    seed: int | None = None
    gui: bool = False
    reward_type: Literal["Dense", "Sparse"] = "Dense"
    action: ActionSettings = ActionSettings()
    timing: TimingSettings = TimingSettings()
    safety: SafetySettings = SafetySettings()
    use_kinect: bool = False  # adds the scene camera's image terms to the observation
    log_internal_state: bool = False
    real: RealSettings = RealSettings()

    @field_validator("reward_type", mode="before")
    @classmethod
    def _capitalised(cls, value):
        # the seeds write "Dense"/"Sparse"; accept any case
        return value.capitalize() if isinstance(value, str) else value


class TableSpec(Model):
    center: tuple[Real, Real]
    top_z: Real
    size: tuple[Positive, Positive]
    thickness: Positive = 0.04


class CameraSpec(Model):
    """A fixed camera over the table: the use_kinect image terms render from it."""

    eye: Vec3  # world frame
    target: Vec3
    fov: Positive = Field(default=60.0, lt=180)  # vertical, degrees
    width: int = Field(default=128, ge=8, le=4096)
    height: int = Field(default=96, ge=8, le=4096)
    near: Positive = 0.1
    far: Positive = 3.0
    terms: list[str] = ["rgb", "depth"]  # image terms, each a key of the Dict observation

    @model_validator(mode="after")
    def _clipping_ordered(self) -> "CameraSpec":
        if self.near >= self.far:
            raise located("far", f"near ({self.near}) must be below far ({self.far})")
        if self.eye == self.target:
            raise located("target", "eye and target coincide: the camera has no view direction")
        return self


class SceneSpec(Model):
    table: TableSpec
    camera: CameraSpec | None = None


class SimSettings(Model):
    physics_hz: Positive = Field(default=240.0, le=100_000)
    solver_iterations: int = Field(default=50, ge=1, le=10_000)


class Workspace(Model):
    """Where the EE may be commanded, in the task frame."""

    min: Vec3
    max: Vec3

    @model_validator(mode="after")
    def _ordered(self) -> "Workspace":
        ordered(self.min, self.max, "workspace")
        return self


class IdEntry(Model):
    backend: str
    goal_env: bool = False
    kwargs: dict[str, Any] = {}


class Registration(Model):
    max_episode_steps: int = Field(default=100, ge=1, le=MAX_EPISODE_STEPS_LIMIT)
    ids: dict[str, IdEntry] = Field(min_length=1)
