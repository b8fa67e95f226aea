"""The validated shape of a composed env spec.

Every model forbids unknown keys, so a typo is reported with its dotted path
and the nearest valid name instead of being silently ignored.
"""

from __future__ import annotations

from typing import Any, Literal

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

Vec3 = tuple[float, float, float]
PositiveFloat = Annotated[float, Field(gt=0)]
Size2 = tuple[PositiveFloat, PositiveFloat]
Size3 = tuple[PositiveFloat, PositiveFloat, PositiveFloat]


class Model(BaseModel):
    # NaN and infinity are refused in every float of a spec: a NaN margin compares false
    # with everything and would switch a check off without a word.
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


# --------------------------------------------------------------------- robot


class UrdfPart(Model):
    airo_models: str | None = None
    urdf: str | None = None
    prefix: str = ""
    parent: str | None = None
    xyz: Vec3 = (0.0, 0.0, 0.0)
    rpy: Vec3 = (0.0, 0.0, 0.0)

    @model_validator(mode="after")
    def _one_source(self) -> "UrdfPart":
        if (self.airo_models is None) == (self.urdf is None):
            raise ValueError("give exactly one of 'airo_models' or 'urdf'")
        return self


class FrameSpec(Model):
    parent: str
    xyz: Vec3 = (0.0, 0.0, 0.0)
    rpy: Vec3 = (0.0, 0.0, 0.0)


class ModelSpec(Model):
    parts: list[UrdfPart] = Field(min_length=1)
    frames: dict[str, FrameSpec] = {}

    @model_validator(mode="after")
    def _attached_parts_name_parent(self) -> "ModelSpec":
        for index, part in enumerate(self.parts[1:], start=1):
            if part.parent is None:
                raise ValueError(f"parts[{index}] needs 'parent': the link it is mounted on")
        return self


class ArmJoint(Model):
    name: str
    lower: float
    upper: float
    label: str = ""

    @model_validator(mode="after")
    def _ordered(self) -> "ArmJoint":
        if self.lower >= self.upper:
            raise ValueError(f"lower ({self.lower}) must be below upper ({self.upper})")
        return self


class JointStateEntry(Model):
    """One entry of the robot's /joint_states message, in message order."""

    name: str
    urdf: str | None = None  # the URDF joint in simulation, when its name differs
    position: tuple[float, float]
    velocity: tuple[float, float]
    unit: Literal["rad", "m"] = "rad"

    @property
    def urdf_joint(self) -> str:
        return self.urdf or self.name


class ContactSpec(Model):
    """Contact parameters of the links that touch a grasped object."""

    links: list[str] = []
    lateral_friction: float = Field(default=1.0, ge=0)
    spinning_friction: float = Field(default=0.0, ge=0)
    rolling_friction: float = Field(default=0.0, ge=0)
    friction_anchor: bool = True  # pins static friction in place: without it a held object creeps out


class GripperSpec(Model):
    joint: str  # the driven URDF joint
    open: float
    closed: float
    mimic: dict[str, float] = {}  # URDF joint -> multiplier of the driven joint
    force: float = 100.0
    max_velocity: float = Field(default=1.0, gt=0)  # of the driven joint, per second
    grasp_threshold: float | None = None  # closed at least this far when holding something
    closing_axis: Literal["x", "y", "z"] = "y"  # the EE frame axis along which the fingers close
    pads: ContactSpec = ContactSpec()
    label: str = "gripper command (absolute)"

    @model_validator(mode="after")
    def _distinct(self) -> "GripperSpec":
        if self.open == self.closed:
            raise ValueError("open and closed must differ")
        if self.grasp_threshold is not None and not self.low <= self.grasp_threshold <= self.high:
            raise ValueError(f"grasp_threshold {self.grasp_threshold} lies outside [{self.low}, {self.high}]")
        return self

    def closure(self, value):
        """0 when open, 1 when closed, whichever way the joint runs."""
        return (value - self.open) / (self.closed - self.open)

    @property
    def low(self) -> float:
        return min(self.open, self.closed)

    @property
    def high(self) -> float:
        return max(self.open, self.closed)


class RobotSafety(Model):
    """What the safety check needs beyond the URDF's collision geometry."""

    # The generated list of link pairs that need no self-collision check (adjacent, always
    # touching or never near), relative to the robot YAML; `envfactory collision-pairs` writes it.
    collision_pairs: str | None = None
    # Extra clearance (m) a link keeps from everything, beyond the margin: cables, tools, doubt.
    padding: dict[str, Annotated[float, Field(ge=0)]] = {}


class PedestalSpec(Model):
    """A stand under the robot base: a top plate on four legs."""

    size: Size2
    rgba: tuple[float, float, float, float] = (0.3, 0.3, 0.32, 1.0)


class RosTopic(Model):
    topic: str
    type: str


class ArmCommand(RosTopic):
    # joint_trajectory: trajectory_msgs/JointTrajectory, one point at time_from_start (ur_robot_driver)
    # joint_group: interbotix_xs_msgs/JointGroupCommand {name: group, cmd: positions} (xs_sdk)
    encoding: Literal["joint_trajectory", "joint_group"]
    group: str = "arm"


class GripperCommand(RosTopic):
    # float64_array: std_msgs/Float64MultiArray with the one driven value (the Robotiq knuckle)
    # joint_single: interbotix_xs_msgs/JointSingleCommand {name, cmd} (xs_sdk gripper in linear_position mode)
    encoding: Literal["float64_array", "joint_single"]
    name: str = "gripper"


class StaticTransform(Model):
    """Where a frame sits in its parent: lets object poses from a camera reach the task frame."""

    parent: str
    xyz: Vec3 = (0.0, 0.0, 0.0)
    rpy: Vec3 = (0.0, 0.0, 0.0)


class RosSpec(Model):
    """The robot's topics under rosbridge; every one can be overridden in YAML or by kwarg."""

    joint_states: RosTopic
    arm_command: ArmCommand
    gripper_command: GripperCommand | None = None
    object_poses: dict[str, RosTopic] = {}  # object name -> geometry_msgs/PoseStamped topic
    task_frame_id: str  # the ROS frame of the task frame (goals and observations)
    static_transforms: dict[str, StaticTransform] = {}  # frame -> its pose in the parent frame
    use_tf: bool = False  # also learn transforms from /tf and /tf_static


class RobotSpec(Model):
    name: str
    label: str
    model: ModelSpec
    mount: Vec3  # world position of the robot base
    pedestal: PedestalSpec | None = None
    task_frame: Literal["world", "base"]
    arm_joints: list[ArmJoint] = Field(min_length=1)
    home: list[float]
    ee_frame: str
    ee_bounds: tuple[Vec3, Vec3]  # EE position bounds in the task frame (obs and absolute EE actions)
    top_down_rpy: Vec3 | None = None  # task-frame EE orientation that points the gripper straight down
    joint_states: list[JointStateEntry] = Field(min_length=1)
    joint_states_topic: str
    gripper: GripperSpec | None = None
    arm_force: float = 150.0
    arm_max_velocity: float = 3.15
    safety: RobotSafety = RobotSafety()
    ros: RosSpec | None = None

    @property
    def task_origin_world(self) -> Vec3:
        """Where the task frame sits in the world: the robot base, or the world origin."""
        return self.mount if self.task_frame == "base" else (0.0, 0.0, 0.0)

    @property
    def state_names(self) -> list[str]:
        """The /joint_states names, in message order."""
        return [entry.name for entry in self.joint_states]

    @property
    def arm_state_indices(self) -> list[int]:
        """Where each arm joint (action order) sits in /joint_states."""
        urdf_names = [entry.urdf_joint for entry in self.joint_states]
        return [urdf_names.index(joint.name) for joint in self.arm_joints]

    @property
    def gripper_state_index(self) -> int | None:
        """Where the driven gripper joint sits in /joint_states, if there is a gripper."""
        if self.gripper is None:
            return None
        return [entry.urdf_joint for entry in self.joint_states].index(self.gripper.joint)

    @property
    def arm_state_names(self) -> list[str]:
        """The arm joints' /joint_states names, in action order: what arm commands carry."""
        return [self.joint_states[i].name for i in self.arm_state_indices]

    @model_validator(mode="after")
    def _consistent(self) -> "RobotSpec":
        if len(self.home) != len(self.arm_joints):
            raise ValueError(f"home has {len(self.home)} values for {len(self.arm_joints)} arm_joints")
        for joint, value in zip(self.arm_joints, self.home):
            if not joint.lower <= value <= joint.upper:
                raise ValueError(f"home value {value} of {joint.name} is outside [{joint.lower}, {joint.upper}]")
        urdf_names = {entry.urdf_joint for entry in self.joint_states}
        missing = [j.name for j in self.arm_joints if j.name not in urdf_names]
        if missing:
            raise ValueError(f"arm joints {missing} are missing from joint_states")
        return self


# ---------------------------------------------------------------------- task


class TermRef(Model):
    """A term by name, its params and, for rewards, its weight."""

    term: str
    weight: float = 1.0
    params: dict[str, Any] = {}


class SpawnSpec(Model):
    position: Vec3  # the object's centre at rest, task frame
    random: bool = True  # random_cube_spawn
    offset: tuple[float, float] = (0.05, 0.05)  # random_offset: ± metres in x and y

    @field_validator("offset")
    @classmethod
    def _non_negative(cls, offset):
        if min(offset) < 0:
            raise ValueError(f"offset {list(offset)} must not be negative")
        return offset


class ObjectSpec(Model):
    shape: Literal["box"] = "box"
    size: float = Field(gt=0)  # edge length
    rgba: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 1.0)
    mass: float = Field(gt=0)
    friction: float = Field(default=1.0, ge=0)
    spinning_friction: float = Field(default=0.0, ge=0)
    rolling_friction: float = Field(default=0.0, ge=0)
    spawn: SpawnSpec


class GripperUse(Model):
    in_action: bool = False
    at_reset: Literal["open", "closed", "unchanged"] | float = "unchanged"  # or a joint value


class LiftStage(Model):
    """The multi_goal curriculum: lift the object above its spawn point, then go for the goal."""

    enabled: bool = True  # multi_goal
    height: float = Field(default=0.15, gt=0)  # lift_height


class GoalSpec(Model):
    achieved: str  # "ee.position" or "<object>.position"
    tolerance: float = Field(gt=0)
    box: tuple[Vec3, Vec3]
    random: bool = True  # random_goal; otherwise the static goal below
    static: Vec3 | None = None  # the goal when random is false; the box centre if unset
    sampling_tries: int = Field(default=20, ge=1)
    lift: LiftStage | None = None

    @field_validator("box")
    @classmethod
    def _ordered_box(cls, box):
        low, high = box
        if any(lo > hi for lo, hi in zip(low, high)):
            raise ValueError(f"box low {list(low)} exceeds high {list(high)}")
        return box

    @model_validator(mode="after")
    def _static_in_box(self) -> "GoalSpec":
        low, high = self.box
        if self.static is not None and not all(lo <= v <= hi for v, lo, hi in zip(self.static, low, high)):
            raise ValueError(f"static goal {list(self.static)} lies outside the goal box")
        return self

    @property
    def static_goal(self) -> Vec3:
        if self.static is not None:
            return self.static
        low, high = self.box
        return tuple((lo + hi) / 2 for lo, hi in zip(low, high))


class RewardSets(Model):
    sparse: dict[str, TermRef]
    dense: dict[str, TermRef]


class TerminationRef(Model):
    term: str
    params: dict[str, Any] = {}
    when: Literal["always", "sparse", "dense"] = "always"


class ExpertRef(Model):
    """The scripted policy that solves the task, and its robot-specific params."""

    policy: str
    params: dict[str, Any] = {}

    @model_validator(mode="before")
    @classmethod
    def _bare_name(cls, value):
        return {"policy": value} if isinstance(value, str) else value


class TaskSpec(Model):
    name: str
    label: str
    gripper: GripperUse = GripperUse()
    objects: dict[str, ObjectSpec] = {}
    goal: GoalSpec
    observation: list[dict[str, dict[str, Any]]] = Field(min_length=1)
    reward: RewardSets
    termination: dict[str, TerminationRef] = {}
    expert: ExpertRef | None = None
    kwargs: dict[str, str] = {}

    @field_validator("observation", mode="before")
    @classmethod
    def _normalise_observation(cls, entries):
        # YAML lets a term be a bare name or a one-key mapping to its params.
        normalised = []
        for index, entry in enumerate(entries or []):
            if isinstance(entry, str):
                normalised.append({entry: {}})
            elif isinstance(entry, dict) and len(entry) == 1:
                (name, params), = entry.items()
                normalised.append({name: dict(params or {})})
            else:
                raise ValueError(f"entry {index} must be a term name or a one-key mapping of name to params")
        return normalised


# ----------------------------------------------------------------------- env


class ActionSettings(Model):
    ee: bool = False
    delta: bool = True
    delta_coeff: float = Field(default=0.05, gt=0)


class TimingSettings(Model):
    loop_rate: float = Field(default=10.0, gt=0)
    action_cycle_time: float = Field(default=0.5, gt=0)
    action_speed: float = Field(default=0.2, gt=0)
    realtime: bool = False

    @model_validator(mode="after")
    def _cycle_covers_loop(self) -> "TimingSettings":
        if self.action_cycle_time < 1.0 / self.loop_rate - 1e-9:
            raise ValueError(
                f"action_cycle_time ({self.action_cycle_time}) must be >= 1 / loop_rate ({1.0 / self.loop_rate:g})"
            )
        return self


class SafetySettings(Model):
    floor_z: float = 0.0
    surface_margin: float = Field(default=0.015, gt=0)  # from the table, the floor and the arm itself
    table_footprint_margin: float = Field(default=0.03, ge=0)
    max_joint_delta: float = Field(default=0.5, gt=0)


class RealSettings(Model):
    """The real robot over rosbridge: connection, gates and limits. Sim ignores these."""

    host: str = "localhost"
    port: int = Field(default=9090, ge=1, le=65535)
    allow_motion: bool = False  # allow_real_robot_motion; ALLOW_REAL_ROBOT_MOTION=1 also allows
    connect_timeout_s: float = Field(default=5.0, gt=0)
    reconnect_tries: int = Field(default=10, ge=1)  # connection tries at reset, backoff 0.25 s doubling to 2 s
    joint_state_timeout_s: float = Field(default=0.5, gt=0)
    cube_pose_timeout_s: float = Field(default=1.0, gt=0)
    deadman_s: float = Field(default=1.5, gt=0)  # no command for this long: the arm is stopped
    follow_timeout_s: float = Field(default=1.0, gt=0)  # a commanded arm that has not moved by then: abort
    reset_speed: float = Field(default=0.3, gt=0)  # rad/s of the slowest-allowed move home at reset
    reset_timeout_s: float = Field(default=30.0, gt=0)
    reset_tolerance: float = Field(default=0.02, gt=0)  # rad: home counts as reached
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
    center: tuple[float, float]
    top_z: float
    size: Size2
    thickness: PositiveFloat = 0.04

    @model_validator(mode="after")
    def _stands_on_the_floor(self) -> "TableSpec":
        if self.top_z <= self.thickness:
            raise ValueError(f"top_z ({self.top_z}) must be above the top's thickness ({self.thickness})")
        return self


class ObstacleSpec(Model):
    """A fixed box in the scene (world frame): the simulator builds it and the safety check avoids it."""

    center: Vec3
    size: Size3
    rgba: tuple[float, float, float, float] = (0.5, 0.5, 0.5, 1.0)


class CameraSpec(Model):
    """A fixed camera over the table: the use_kinect image terms render from it."""

    eye: Vec3  # world frame
    target: Vec3
    fov: float = Field(default=60.0, gt=0, lt=180)  # vertical, degrees
    width: int = Field(default=128, ge=8)
    height: int = Field(default=96, ge=8)
    near: float = Field(default=0.1, gt=0)
    far: float = Field(default=3.0, gt=0)
    terms: list[str] = ["rgb", "depth"]  # image terms, each a key of the Dict observation

    @model_validator(mode="after")
    def _clipping_ordered(self) -> "CameraSpec":
        if self.near >= self.far:
            raise ValueError(f"near ({self.near}) must be below far ({self.far})")
        return self


class SceneSpec(Model):
    table: TableSpec
    obstacles: dict[str, ObstacleSpec] = {}
    camera: CameraSpec | None = None


class SimSettings(Model):
    physics_hz: float = Field(default=240.0, gt=0)
    solver_iterations: int = Field(default=50, ge=1)


class Workspace(Model):
    min: Vec3
    max: Vec3

    @model_validator(mode="after")
    def _ordered(self) -> "Workspace":
        if any(lo >= hi for lo, hi in zip(self.min, self.max)):
            raise ValueError(f"min {list(self.min)} must be below max {list(self.max)} on every axis")
        return self


class IdEntry(Model):
    backend: str
    goal_env: bool = False
    kwargs: dict[str, Any] = {}


class Registration(Model):
    max_episode_steps: int = Field(default=100, ge=1)
    ids: dict[str, IdEntry] = Field(min_length=1)


class EnvSpec(Model):
    """A composed env family: robot x task, plus the IDs it registers."""

    robot: RobotSpec
    task: TaskSpec
    env: EnvSettings = EnvSettings()
    scene: SceneSpec
    sim: SimSettings = SimSettings()
    workspace: Workspace
    registration: Registration
    kwargs: dict[str, str] = {}

    @model_validator(mode="after")
    def _gripper_needed(self) -> "EnvSpec":
        uses_gripper = self.task.gripper.in_action or self.task.gripper.at_reset != "unchanged"
        if uses_gripper and self.robot.gripper is None:
            raise ValueError(f"task {self.task.name!r} uses a gripper but robot {self.robot.name!r} declares none")
        at_reset = self.task.gripper.at_reset
        if isinstance(at_reset, float) and not self.robot.gripper.low <= at_reset <= self.robot.gripper.high:
            raise ValueError(f"task.gripper.at_reset {at_reset} lies outside the gripper's range "
                             f"[{self.robot.gripper.low}, {self.robot.gripper.high}]")
        return self

    @property
    def gripper_at_reset(self) -> float | None:
        """The gripper joint value a reset commands, or None to leave it as it is."""
        at_reset, gripper = self.task.gripper.at_reset, self.robot.gripper
        if at_reset == "unchanged" or gripper is None:
            return None
        return {"open": gripper.open, "closed": gripper.closed}.get(at_reset, at_reset)

    def kwarg_aliases(self) -> dict[str, str]:
        return {**self.kwargs, **self.task.kwargs}
