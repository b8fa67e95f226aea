"""Env settings (the reference pages' kwargs land here), the scene, the workspace and the registration block."""

from __future__ import annotations

import warnings
from typing import Any, Literal

from pydantic import Field, field_validator, model_validator

from envfactory.schema.base import Model, Position, Rgba, in_unit_range, located, ordered
from envfactory.schema.numbers import TWO_PI, Coordinate, Length, NonNegative, Positive

# Largest joint change one action may command: a full turn (no revolute joint can travel further).
MAX_JOINT_DELTA_LIMIT = TWO_PI
# A registration entry beyond this many steps per episode is a typo, not a task.
MAX_EPISODE_STEPS_LIMIT = 1_000_000


class ActionSettings(Model):
    ee: bool = False
    delta: bool = True
    # The action box times delta_coeff is the step: above 1 the step outgrows the box.
    delta_coeff: Positive = Field(default=0.05, le=1.0)
    normalize: bool = False  # normalize_actions: the policy acts in [-1, 1] (envfactory.compiler.normalization)
    # ee_yaw_action: EE mode's action gains a Δyaw row, a turn of the tool about the vertical, so a policy can
    # square a gripper's face to a line (Slide's strike). Joint mode turns the wrist through its own rows.
    yaw: bool = False


class ObservationSettings(Model):
    # normalize_observations: every vector column and goal scaled by its declared bounds
    # (envfactory.compiler.normalization)
    normalize: bool = False
    camera_images: bool = False  # use_kinect: the scene camera's image terms join the observation


class TimingSettings(Model):
    loop_rate: Positive = Field(default=10.0, le=1000.0)  # Hz
    action_cycle_time: Positive = Field(default=0.5, le=60.0)  # s of motion per step
    action_speed: Positive = Field(default=0.2, le=60.0)  # s to reach each joint target
    realtime: bool = False

    @model_validator(mode="after")
    def _cycle_covers_loop(self) -> "TimingSettings":
        if self.action_cycle_time < 1.0 / self.loop_rate - 1e-9:
            raise located(
                "action_cycle_time",
                f"action_cycle_time ({self.action_cycle_time}) must be >= 1 / loop_rate ({1.0 / self.loop_rate:g})",
            )
        return self


class SafetySettings(Model):
    floor_z: Coordinate = 0.0
    surface_margin: Positive = Field(default=0.015, le=0.5)  # m: zero would let a link touch the table
    table_footprint_margin: NonNegative = Field(default=0.03, le=1.0)
    max_joint_delta: Positive = Field(default=0.5, le=MAX_JOINT_DELTA_LIMIT)


class RealSettings(Model):
    """The real robot over rosbridge: connection, gates and limits. Sim ignores these."""

    host: str = "localhost"
    port: int = Field(default=9090, ge=1, le=65535)
    allow_motion: bool = False  # allow_real_robot_motion; ALLOW_REAL_ROBOT_MOTION=1 also allows
    # Upper bounds: a staleness or deadman limit of minutes is a gate switched off.
    connect_timeout_s: Positive = Field(default=5.0, le=120.0)
    reconnect_tries: int = Field(default=10, ge=1, le=100)  # connection tries at reset, backoff 0.25 s doubling to 2 s
    joint_state_timeout_s: Positive = Field(default=0.5, le=5.0)
    cube_pose_timeout_s: Positive = Field(default=1.0, le=10.0)
    deadman_s: Positive = Field(default=1.5, le=10.0)  # no command for this long: the arm is stopped
    follow_timeout_s: Positive = Field(default=1.0, le=10.0)  # a commanded arm that has not moved by then: abort
    reset_speed: Positive = Field(default=0.3, le=3.15)  # rad/s of the slowest-allowed move home at reset
    reset_timeout_s: Positive = Field(default=30.0, le=600.0)
    reset_tolerance: Positive = Field(default=0.02, le=0.5)  # rad: home counts as reached
    auto_launch_cube_tracker: bool = False  # True is refused: the user starts the tracker
    cube_tracker_camera: Literal["kinect2", "zed2", "d405"] = "kinect2"
    cube_tracker_target_frame: str = ""  # if set, object poses must be given in (or transform to) this frame


class EnvSettings(Model):
    seed: int | None = None
    gui: bool = False
    reward_type: Literal["Dense", "Sparse"] = "Dense"
    action: ActionSettings = ActionSettings()
    observation: ObservationSettings = ObservationSettings()
    timing: TimingSettings = TimingSettings()
    safety: SafetySettings = SafetySettings()
    log_internal_state: bool = False
    real: RealSettings = RealSettings()

    @field_validator("reward_type", mode="before")
    @classmethod
    def _capitalised(cls, value):
        # the reference pages write "Dense"/"Sparse"; accept any case
        return value.capitalize() if isinstance(value, str) else value


class TableSpec(Model):
    center: tuple[Coordinate, Coordinate]
    top_z: Coordinate
    size: tuple[Length, Length]
    thickness: Length = 0.04

    @model_validator(mode="after")
    def _stands_on_the_floor(self) -> "TableSpec":
        if self.top_z <= self.thickness:
            raise located("top_z", f"top_z ({self.top_z}) must be above the top's thickness ({self.thickness})")
        return self


class ObstacleSpec(Model):
    """A fixed box in the scene (world frame): the simulator builds it and the safety check avoids it."""

    center: Position
    size: tuple[Length, Length, Length]
    rgba: Rgba = (0.5, 0.5, 0.5, 1.0)

    @model_validator(mode="after")
    def _colour(self) -> "ObstacleSpec":
        in_unit_range(self.rgba)
        return self


class CameraSpec(Model):
    """A fixed camera over the table: the use_kinect image terms render from it."""

    eye: Position  # world frame
    target: Position
    fov: Positive = Field(default=60.0, lt=180)  # vertical, degrees
    width: int = Field(default=128, ge=8, le=4096)
    height: int = Field(default=96, ge=8, le=4096)
    near: Positive = 0.1
    far: Positive = Field(default=3.0, le=100.0)
    terms: list[str] = ["rgb", "depth"]  # image terms, each a key of the Dict observation

    @model_validator(mode="after")
    def _clipping_ordered(self) -> "CameraSpec":
        if self.near >= self.far:
            raise located("near", f"near ({self.near}) must be below far ({self.far})")
        if self.eye == self.target:
            raise located("target", "eye and target coincide: the camera has no view direction")
        return self


class SceneSpec(Model):
    table: TableSpec
    obstacles: dict[str, ObstacleSpec] = {}
    camera: CameraSpec | None = None


class MujocoSettings(Model):
    """MuJoCo's own rate and solver: chosen by measured tracking (tests/test_mujoco.py), not PyBullet's."""

    # at 240 Hz the VX300S's light wrist drifts up to 7 mrad off the commanded line; at 480 Hz every arm
    # stays within 0.5 mrad
    physics_hz: Positive = Field(default=480.0, le=100_000)
    solver_iterations: int = Field(default=50, ge=1, le=10_000)
    # MuJoCo's soft contacts let a squeezed cube creep out of the pads (~1 mm/s in a UR5e carry, until it
    # drops); the no-slip pass removes that creep (tests/test_mujoco.py measures a held cube's slip)
    noslip_iterations: int = Field(default=3, ge=0, le=1_000)
    # with sim.fidelity fast, a cube held in a grasp that did not slip rides with the hand while the carry is
    # proven clear (envfactory/backends/mujoco/held.py); false: every carry is simulated (the reference)
    carry_held: bool = True


class SimSettings(Model):
    # which physics engine simulates a Sim ID (the `engine` kwarg): the same robot, scene and objects in both
    engine: Literal["pybullet", "mujoco"] = "pybullet"
    physics_hz: Positive = Field(default=240.0, le=100_000)
    solver_iterations: int = Field(default=50, ge=1, le=10_000)
    # PyBullet's positionGain of the arm motors: the share of a joint's position error its motor
    # corrects per substep. PyBullet's default, 0.1, leaves the arm a few hundredths of a milliradian
    # off its target under gravity at the end of every cycle, and delta actions carry that on from step
    # to step (measured in tests/test_fidelity.py); 1.0 holds the target.
    motor_position_gain: float = Field(default=1.0, gt=0.0, le=1.0)
    # full: every step simulates the whole action cycle (the reference). fast: a motion proven clear
    # of every movable object is played kinematically and a scene at rest is not stepped
    # (envfactory/backends/pybullet/fast_cycles.py, envfactory/backends/mujoco/fast_cycles.py); its distance
    # to full is measured in tests/test_fidelity.py and tests/test_mujoco_fidelity.py
    fidelity: Literal["fast", "full"] = "fast"
    mujoco: MujocoSettings = MujocoSettings()


class Workspace(Model):
    """Where the EE may be commanded, in the task frame."""

    min: Position
    max: Position

    @model_validator(mode="after")
    def _ordered(self) -> "Workspace":
        ordered(self.min, self.max, "workspace")
        return self


# Registration backends spelled the old way: a simulated ID was registered as `pybullet` whichever engine ran it
LEGACY_BACKENDS = {"pybullet": "sim"}
SIMULATED = "sim"  # the backend of a simulated ID; its engine is the spec's sim.engine (the engine kwarg)


class IdEntry(Model):
    backend: str  # sim (its engine from sim.engine), rosbridge, or a backend joined through an entry point
    goal_env: bool = False
    kwargs: dict[str, Any] = {}

    @field_validator("backend")
    @classmethod
    def _current_spelling(cls, value: str) -> str:
        if value in LEGACY_BACKENDS:
            warnings.warn(
                f"registration backend {value!r} is the old spelling of {LEGACY_BACKENDS[value]!r} (the "
                f"engine is sim.engine's, or the engine kwarg's): write backend: {LEGACY_BACKENDS[value]}",
                DeprecationWarning,
                stacklevel=2,
            )
            return LEGACY_BACKENDS[value]
        return value


class Registration(Model):
    max_episode_steps: int = Field(default=100, ge=1, le=MAX_EPISODE_STEPS_LIMIT)
    ids: dict[str, IdEntry] = Field(min_length=1)
