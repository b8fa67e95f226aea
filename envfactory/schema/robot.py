"""The robot: its URDF parts, arm joints, gripper, joint-state message and limits."""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import Field, model_validator

from envfactory.schema.base import Model, Position, Rgba, Rpy, in_unit_range, located, ordered
from envfactory.schema.errors import suggest
from envfactory.schema.numbers import TWO_PI, Friction, Length, NonNegative, Positive, Real
from envfactory.schema.randomization import SensingRef
from envfactory.schema.ros import RosSpec
from envfactory.schema.units import out_of_range_hint

# The joint-delta action box of an arm joint that declares none: symmetric, ±π per
# unit action before delta_coeff scales it (the reference pages' UR5e convention).
DEFAULT_JOINT_DELTA = 3.14
# Motor limits no arm on a table exceeds: above them a value is a typo.
MAX_EFFORT = 10_000.0  # N·m or N
MAX_JOINT_VELOCITY = 20.0  # rad/s or m/s
Effort = Annotated[Positive, Field(le=MAX_EFFORT)]
# Observation bounds of one joint reading (rad, m, or per second): beyond ±100 they bound nothing.
StateBound = Annotated[Real, Field(ge=-100.0, le=100.0)]
Velocity = Annotated[Positive, Field(le=MAX_JOINT_VELOCITY)]
# One unit of action in a delta row times delta_coeff (at most 1) is the step: past a full turn it is a typo.
DeltaBound = Annotated[Real, Field(ge=-TWO_PI, le=TWO_PI)]


_PART_SOURCES = ("airo_models", "pybullet_data", "urdf")


class UrdfPart(Model):
    # Where the part's URDF comes from: exactly one of these three
    airo_models: str | None = None  # a robot name airo-models ships
    pybullet_data: str | None = None  # a path inside the installed pybullet_data package
    urdf: str | None = None  # a file, relative to the robot YAML's folder
    prefix: str = ""
    parent: str | None = None
    xyz: Position = (0.0, 0.0, 0.0)
    rpy: Rpy = (0.0, 0.0, 0.0)

    @model_validator(mode="after")
    def _one_source(self) -> "UrdfPart":
        given = [source for source in _PART_SOURCES if getattr(self, source) is not None]
        if len(given) != 1:
            named = f"both {given[0]!r} and {given[1]!r}" if len(given) > 1 else "none"
            raise ValueError(f"give exactly one of {', '.join(map(repr, _PART_SOURCES))} (given: {named})")
        return self


class FrameSpec(Model):
    parent: str
    xyz: Position = (0.0, 0.0, 0.0)
    rpy: Rpy = (0.0, 0.0, 0.0)


class InertialSpec(Model):
    """A link's mass properties, in place of the URDF's: its mass, its centre of mass in the link frame and its
    inertia tensor about that centre, in the link frame's axes."""

    mass: Annotated[Positive, Field(le=1000.0)]  # kg
    xyz: Position  # m
    inertia: tuple[Real, Real, Real, Real, Real, Real]  # ixx, iyy, izz, ixy, ixz, iyz, kg m^2

    @model_validator(mode="after")
    def _physical(self) -> "InertialSpec":
        ixx, iyy, izz, ixy, ixz, iyz = self.inertia
        tensor = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        moments = np.linalg.eigvalsh(tensor)
        # a real body's principal moments are positive and each at most the sum of the other two
        if moments.min() <= 0 or 2 * moments.max() > moments.sum() * (1 + 1e-9):
            raise located(
                "inertia",
                f"no body has this inertia: principal moments {np.round(moments, 9).tolist()} must be positive, "
                "each at most the sum of the other two",
            )
        return self


class ModelSpec(Model):
    parts: list[UrdfPart] = Field(min_length=1)
    frames: dict[str, FrameSpec] = {}
    # package:// mesh paths: package name -> folder, relative to the robot YAML's folder
    packages: dict[str, str] = {}
    # link name -> mass properties replacing the URDF's (a vendor file with placeholder inertia)
    inertials: dict[str, InertialSpec] = {}

    @model_validator(mode="after")
    def _attached_parts_name_parent(self) -> "ModelSpec":
        base = self.parts[0]
        if base.parent is not None or any(base.xyz) or any(base.rpy):
            raise located(
                "parts.0",
                "parts[0] is the base: it takes no parent, xyz or rpy (place the robot with "
                "'mount' and turn it with 'mount_rpy')",
            )
        for index, part in enumerate(self.parts[1:], start=1):
            if part.parent is None:
                raise ValueError(f"parts[{index}] needs 'parent': the link it is mounted on")
        return self


class ArmJoint(Model):
    name: str
    lower: Real
    upper: Real
    label: str = ""
    # The joint-delta action row: ± one number, or [min, max] around zero. Independent of
    # the position limits, which bound the target, not the step.
    delta: Annotated[Positive, Field(le=TWO_PI)] | tuple[DeltaBound, DeltaBound] = DEFAULT_JOINT_DELTA
    effort: Effort | None = None  # N·m (N for a prismatic joint); the robot's arm_force if unset
    velocity: Velocity | None = None  # rad/s (m/s); the robot's arm_max_velocity if unset

    @model_validator(mode="after")
    def _ordered(self) -> "ArmJoint":
        if self.lower >= self.upper:
            raise located("upper", f"lower ({self.lower}) must be below upper ({self.upper})")
        if isinstance(self.delta, tuple) and not self.delta[0] < 0 < self.delta[1]:
            raise located("delta", f"delta {list(self.delta)} must contain 0 strictly inside (zero is 'hold still')")
        # A delta row bounds one step from where the joint is: no step can be longer than the whole range,
        # and a row that allows one makes most of the action space overshoot the limits (clipped and
        # penalised as out of bounds)
        span = self.upper - self.lower
        widest = max(abs(bound) for bound in self.delta_box)
        if widest > span + 1e-9:
            written = f"±{self.delta:g}" if isinstance(self.delta, float) else str(list(self.delta))
            if "delta" not in self.model_fields_set:
                written = f"{written} (the default: this joint declares none)"
            example = (
                f"[{self.lower:g}, {self.upper:g}] (the range itself, the original suite's convention)"
                if self.lower < 0 < self.upper
                else f"{span:.3g}"
            )
            raise located(
                "delta",
                f"delta {written} rad allows a step of {widest:g} rad, larger than the joint's "
                f"whole range [{self.lower:g}, {self.upper:g}] ({span:.3g} rad); valid: steps "
                f"within ±{span:.3g}, e.g. delta {example}",
            )
        return self

    @property
    def delta_box(self) -> tuple[float, float]:
        return (-self.delta, self.delta) if isinstance(self.delta, float) else self.delta


class HornLinkage(Model):
    """An Interbotix gripper's motor horn and the arm that links it to the fingers: xs_sdk publishes the horn's
    angle, π/2 - acos((r² + f² - a²) / (2 r f)) for a finger at f; a simulator, which drives the finger, reads the
    angle the driver would publish."""

    finger: str  # the finger's URDF joint
    radius: Length  # the motor config's horn_radius, m
    arm: Length  # its arm_length, m

    @model_validator(mode="after")
    def _reaches(self) -> "HornLinkage":
        if self.arm <= self.radius:
            raise located("arm", f"an arm of {self.arm} m no longer than the horn ({self.radius} m) cannot link it")
        return self


class JointStateEntry(Model):
    """One entry of the robot's /joint_states message, in message order."""

    name: str
    urdf: str | None = None  # the URDF joint in simulation, when its name differs
    position: tuple[StateBound, StateBound]
    velocity: tuple[StateBound, StateBound]
    unit: Literal["rad", "m"] = "rad"
    # False: the real driver does not publish this joint (a gripper jaw that only the maker's simulation
    # publishes); a Real ID reads the gripper's last completed command there
    published: bool = True
    # The driver publishes this joint's velocity as 0 whatever it does (xs_sdk's fingers): so does a simulator
    reports_velocity: bool = True
    horn: HornLinkage | None = None  # the joint is a gripper motor's horn, read through its linkage in simulation

    @model_validator(mode="after")
    def _ordered(self) -> "JointStateEntry":
        ordered(self.position[0], self.position[1], "position")
        ordered(self.velocity[0], self.velocity[1], "velocity")
        return self

    @property
    def urdf_joint(self) -> str:
        return self.urdf or self.name


class ContactSpec(Model):
    """Contact parameters of the links that touch a grasped object."""

    links: list[str] = []
    lateral_friction: Friction = 1.0
    spinning_friction: Friction = 0.0
    rolling_friction: Friction = 0.0
    friction_anchor: bool = True  # pins static friction in place: without it a held object creeps out


class GripperSpec(Model):
    joint: str  # the driven URDF joint
    open: Real
    closed: Real
    mimic: dict[str, Real] = {}  # URDF joint -> multiplier of the driven joint
    force: Effort = 100.0
    max_velocity: Velocity = 1.0  # of the driven joint, per second
    grasp_threshold: Real | None = None  # closed at least this far when holding something
    closing_axis: Literal["x", "y", "z"] = "y"  # the EE frame axis along which the fingers close
    pads: ContactSpec = ContactSpec()
    label: str = "gripper command (absolute)"

    @model_validator(mode="after")
    def _distinct(self) -> "GripperSpec":
        if self.open == self.closed:
            raise located("closed", "open and closed must differ")
        if self.grasp_threshold is not None and not self.low <= self.grasp_threshold <= self.high:
            raise located(
                "grasp_threshold", f"grasp_threshold {self.grasp_threshold} lies outside [{self.low}, {self.high}]"
            )
        for name, gain in self.mimic.items():
            if gain == 0:
                raise located(f"mimic.{name}", "a mimic multiplier of 0 would never move its joint")
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
    padding: dict[str, Annotated[NonNegative, Field(le=1.0)]] = {}


class PedestalSpec(Model):
    """A stand under the robot base: a top plate on four legs."""

    size: tuple[Length, Length]
    rgba: Rgba = (0.3, 0.3, 0.32, 1.0)

    @model_validator(mode="after")
    def _colour(self) -> "PedestalSpec":
        in_unit_range(self.rgba)
        return self


class RobotSpec(Model):
    """A robot YAML: its model parts and mount, arm joints and home, the /joint_states layout, the gripper,
    safety additions, the ROS topic map of its real path and its measured sensing."""

    name: str
    label: str
    model: ModelSpec
    mount: Position  # world position of the robot base
    mount_rpy: Rpy = (0.0, 0.0, 0.0)  # world orientation of the robot base (roll, pitch, yaw; URDF convention)
    pedestal: PedestalSpec | None = None
    task_frame: Literal["world", "base"]
    arm_joints: list[ArmJoint] = Field(min_length=1)
    home: list[Real]
    ee_frame: str
    ee_bounds: tuple[Position, Position]  # EE position bounds in the task frame (obs and absolute EE actions)
    top_down_rpy: Rpy | None = None  # task-frame EE orientation that points the gripper straight down
    # The tool orientation EE mode keeps while it moves the EE: "held", the orientation the arm has (the
    # reference pages' EE mode), or "top_down", the gripper turned straight down (top_down_rpy) about as far
    # round as it is now: what manipulation needs of an arm whose home points the gripper forward.
    ee_mode_orientation: Literal["held", "top_down"] = "held"
    joint_states: list[JointStateEntry] = Field(min_length=1)
    # where the real path reads the joint states; a simulation-only robot (no `ros:` block) needs none
    joint_states_topic: str | None = None
    gripper: GripperSpec | None = None
    arm_force: Effort = 150.0  # N·m per arm joint, unless the joint declares its own effort
    # kg: the maker's rated payload; a task object heavier than it (or a mass event reaching past it) is refused
    payload: Annotated[Positive, Field(le=1000.0)] | None = None
    arm_max_velocity: Velocity = 3.15  # rad/s per arm joint, unless the joint declares its own velocity
    safety: RobotSafety = RobotSafety()
    ros: RosSpec | None = None
    # Why a robot has no real path: what `validate` says to a family that declares a Real ID on it
    simulation_only: str | None = None
    # How the robot's real path senses and acts, in whole steps, as `envfactory sensing-spec` measured it from
    # a twin log: joined to every task's randomization sensing terms (a task's own of the same name wins), so a
    # policy trained with randomize=True meets them before the arm does
    sensing: dict[str, SensingRef] = {}

    @property
    def joint_states_source(self) -> str:
        """What the observation tables name as the joint readings' source: the topic, where there is one."""
        if self.joint_states_topic:
            return self.joint_states_topic
        return self.ros.joint_states.topic if self.ros is not None else "joint_states"

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
    def unpublished_gripper_gains(self) -> dict[int, float]:
        """/joint_states index -> multiplier of the gripper value, for the joints the real driver does not
        publish (the driven gripper joint itself, 1.0, and its mimic followers)."""
        gains = {self.gripper.joint: 1.0, **self.gripper.mimic} if self.gripper is not None else {}
        return {index: gains[entry.urdf_joint] for index, entry in enumerate(self.joint_states) if not entry.published}

    @property
    def arm_state_names(self) -> list[str]:
        """The arm joints' /joint_states names, in action order: what arm commands carry."""
        return [self.joint_states[i].name for i in self.arm_state_indices]

    @property
    def arm_efforts(self) -> list[float]:
        return [joint.effort or self.arm_force for joint in self.arm_joints]

    @property
    def arm_velocities(self) -> list[float]:
        return [joint.velocity or self.arm_max_velocity for joint in self.arm_joints]

    @model_validator(mode="after")
    def _consistent(self) -> "RobotSpec":
        if self.simulation_only is not None and self.ros is not None:
            raise located(
                "simulation_only", "a robot with a 'ros:' block has a real path: drop 'simulation_only' or 'ros'"
            )
        if self.ee_mode_orientation == "top_down" and self.top_down_rpy is None:
            raise located(
                "ee_mode_orientation",
                "'top_down' needs top_down_rpy: the orientation that points the gripper straight down",
            )
        tilted = bool(self.mount_rpy[0] or self.mount_rpy[1])
        if tilted and self.task_frame == "base":
            raise located(
                "mount_rpy",
                f"a base tilted by roll/pitch {list(self.mount_rpy[:2])} needs 'task_frame: "
                f"world': a base task frame may only turn about z (yaw), so that its z stays "
                f"up and goals, spawns and the table stay level in it",
            )
        if tilted and self.pedestal is not None:
            raise located(
                "mount_rpy",
                f"a base tilted by roll/pitch {list(self.mount_rpy[:2])} cannot stand on a "
                f"pedestal (its top is level): drop 'pedestal' or the tilt",
            )
        try:
            ordered(self.ee_bounds[0], self.ee_bounds[1], "ee_bounds")
        except ValueError as exc:
            raise located("ee_bounds", str(exc)) from None
        if len(self.home) != len(self.arm_joints):
            raise located("home", f"home has {len(self.home)} values for {len(self.arm_joints)} arm_joints")
        for index, (joint, value) in enumerate(zip(self.arm_joints, self.home)):
            if not joint.lower <= value <= joint.upper:
                raise located(
                    f"home.{index}",
                    f"home value {value} of {joint.name} is outside "
                    f"[{joint.lower}, {joint.upper}]"
                    f"{out_of_range_hint('home', value, joint.lower, joint.upper)}",
                )
        names = [joint.name for joint in self.arm_joints]
        if len(set(names)) != len(names):
            raise located("arm_joints", f"arm_joints repeat a joint: {names}")
        urdf_names = [entry.urdf_joint for entry in self.joint_states]
        if len(set(urdf_names)) != len(urdf_names):
            raise located("joint_states", f"joint_states repeat a URDF joint: {urdf_names}")
        for index, joint in enumerate(self.arm_joints):
            if joint.name not in urdf_names:
                raise located(
                    f"arm_joints.{index}.name",
                    f"arm joint {joint.name!r} is missing from joint_states{suggest(joint.name, urdf_names)}",
                )
        if self.gripper is not None and self.gripper.joint not in urdf_names:
            raise located(
                "gripper.joint",
                f"gripper joint {self.gripper.joint!r} is missing from joint_states"
                f"{suggest(self.gripper.joint, urdf_names)}",
            )
        for index, entry in enumerate(self.joint_states):
            if entry.horn is not None and entry.horn.finger not in urdf_names:
                raise located(
                    f"joint_states.{index}.horn.finger",
                    f"finger {entry.horn.finger!r} is missing from "
                    f"joint_states{suggest(entry.horn.finger, urdf_names)}",
                )
        gripper_joints = {self.gripper.joint, *self.gripper.mimic} if self.gripper is not None else set()
        for index, entry in enumerate(self.joint_states):
            if not entry.published and entry.urdf_joint not in gripper_joints:
                raise located(
                    f"joint_states.{index}.published",
                    f"{entry.name!r} is not published by the driver, but only the gripper's joints "
                    f"({', '.join(sorted(gripper_joints)) or 'none: no gripper'}) can be read from "
                    f"its commands; every other joint must be measured",
                )
        return self
