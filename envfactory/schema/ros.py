"""A robot's topics under rosbridge; every one can be overridden in YAML or by kwarg.

Each topic's messages follow a template (envfactory.schema.messages): `encoding`
names a shipped one or writes one in place.
"""

from __future__ import annotations

import re
from typing import Annotated, Any, ClassVar, Literal

from pydantic import Field, PrivateAttr, model_validator

from envfactory.schema.base import Model, Position, Rpy, located
from envfactory.schema.driver import DriverCall, ServiceType, Settle
from envfactory.schema.errors import suggest
from envfactory.schema.messages import MessageTemplate, checked
from envfactory.schema.numbers import Positive

_MESSAGE_TYPE = re.compile(r"[A-Za-z]\w*/[A-Za-z]\w*")
_FIELD_TYPE = re.compile(r"([a-z]\w*|[A-Za-z]\w*/[A-Za-z]\w*)(\[\d*\])?")


def _same_type(a: str, b: str) -> bool:
    # ROS 2 spells pkg/msg/Type what ROS 1 spells pkg/Type
    return a.replace("/msg/", "/") == b.replace("/msg/", "/")


class RosTopic(Model):
    topic: str
    type: str


class _Templated(RosTopic):
    """A topic whose messages follow a template; ROLE says what kind of message it carries."""

    ROLE: ClassVar[str] = ""
    encoding: str | dict[str, Any]  # a shipped template's name, or a template written in place
    _template: MessageTemplate | None = PrivateAttr(None)

    @model_validator(mode="after")
    def _template_fits(self):
        self._template = checked(self.encoding, self.ROLE)
        return self

    def type_problem(self) -> str | None:
        template = self.template
        if template.type is not None and not _same_type(template.type, self.type):
            return f"type {self.type!r} differs from the type of its message template ({template.type!r})"
        return None

    @property
    def template(self) -> MessageTemplate:
        return self._template


class JointStatesTopic(_Templated):
    ROLE: ClassVar[str] = "joint_state"
    encoding: str | dict[str, Any] = "joint_state"


class PoseTopic(_Templated):
    ROLE: ClassVar[str] = "pose"
    encoding: str | dict[str, Any] = "pose_stamped"


class ArmCommand(_Templated):
    # shipped: joint_trajectory (trajectory_msgs/JointTrajectory, ur_robot_driver),
    # joint_group (interbotix_xs_msgs/JointGroupCommand, xs_sdk)
    ROLE: ClassVar[str] = "arm"
    group: str = "arm"  # $group
    # How long the driver takes to carry out a command whose message holds no $duration: a
    # driver in a time profile (xs_sdk's profile_velocity) spends that long on every command,
    # whatever its length. The digital twin plays commands over it; None when every command
    # carries its own duration.
    profile_time_s: Annotated[Positive, Field(le=60.0)] | None = None  # s


class ActionResultTopic(RosTopic):
    """An action server's result topic (actionlib's X/result, an XActionResult: header, status, result)."""

    within_s: Annotated[Positive, Field(le=60.0)] = 5.0  # a goal with no result by then ends the episode


class GripperStates(Model):
    """What a driver that only opens and closes takes for each: the template's $state."""

    open: int | float | str | bool
    closed: int | float | str | bool


class GripperCommand(_Templated):
    # shipped: float64_array (std_msgs/Float64MultiArray, the Robotiq knuckle),
    # joint_single (interbotix_xs_msgs/JointSingleCommand, xs_sdk gripper in linear_position mode),
    # tool_action_goal (niryo_robot_tools_commander/ToolActionGoal, open/close only)
    ROLE: ClassVar[str] = "gripper"
    name: str = "gripper"  # $name
    states: GripperStates | None = None  # $state
    # $value is the gripper joint's value times this: xs_sdk's linear_position mode takes the distance
    # between the two fingers, twice the left finger's joint value
    scale: Annotated[Positive, Field(le=1000.0)] = 1.0
    # An action server's result topic (actionlib's X/result): each goal's outcome is read, the step waits for
    # it, and a goal that does not succeed ends the episode with the driver's own reason
    result: ActionResultTopic | None = None

    @model_validator(mode="after")
    def _states_declared(self) -> "GripperCommand":
        holds_state = "$state" in self.template.placeholders()
        if holds_state and self.states is None:
            raise located(
                "states",
                "the template holds $state: declare states: {open: ..., closed: ...}, "
                "what the driver takes to open and to close",
            )
        if self.states is not None and not holds_state:
            raise located("states", "states are declared but the template has no $state placeholder")
        return self


class StaticTransform(Model):
    """Where a frame sits in its parent: lets object poses from a camera reach the task frame."""

    parent: str
    xyz: Position = (0.0, 0.0, 0.0)
    rpy: Rpy = (0.0, 0.0, 0.0)


class RosSpec(Model):
    # Which driver the robot runs: the digital twin plays that driver as its maker publishes it; None (any
    # other driver) plays the topic map as declared
    driver: Literal["xs_sdk", "ur_robot_driver", "ned_ros"] | None = None
    # The driver's own configuration on the robot's side, as far as the twin needs it to play the driver (xs_sdk's
    # motor config: the gripper's horn_radius and arm_length); the env itself never reads it
    driver_config: dict[str, float | int | str | bool] = {}
    joint_states: JointStatesTopic
    arm_command: ArmCommand
    gripper_command: GripperCommand | None = None
    object_poses: dict[str, PoseTopic] = {}  # object name -> pose topic (geometry_msgs/PoseStamped by default)
    task_frame_id: str  # the ROS frame of the task frame (goals and observations)
    static_transforms: dict[str, StaticTransform] = {}  # frame -> its pose in the parent frame
    use_tf: bool = False  # also learn transforms from /tf and /tf_static
    # The driver's own message types (type -> field -> field type), as its ROS installation defines
    # them: the digital twin's rosbridge server knows the ROS core types and these.
    message_types: dict[str, dict[str, str]] = {}
    # Service calls at every connection that bring the driver to the env's step (xs_sdk's operating modes)
    setup: list[DriverCall] = []
    service_types: dict[str, ServiceType] = {}  # the driver's own service types, as message_types
    settle: Settle = Settle()  # when a real step's motion is done

    @model_validator(mode="after")
    def _message_types_well_formed(self) -> "RosSpec":
        for type_name, fields in self.message_types.items():
            if not _MESSAGE_TYPE.fullmatch(type_name):
                raise located(f"message_types.{type_name}", "a message type is spelled package/Type")
            for field, field_type in fields.items():
                if not _FIELD_TYPE.fullmatch(field_type):
                    raise located(
                        f"message_types.{type_name}.{field}",
                        f"{field_type!r} is not a field type (a primitive such as float64 or uint8, "
                        "a message type package/Type, either with [] for a list)",
                    )
        return self

    @model_validator(mode="after")
    def _setup_types_declared(self) -> "RosSpec":
        for index, call in enumerate(self.setup):
            if call.type not in self.service_types:
                raise located(
                    f"setup.{index}.type",
                    f"service type {call.type!r} is not declared in "
                    f"ros.service_types (its request and response fields)",
                )
            fields = self.service_types[call.type].request
            for key in call.request:
                if key not in fields:
                    raise located(
                        f"setup.{index}.request.{key}",
                        f"{call.type} has no request field {key!r}{suggest(key, fields)}",
                    )
        for type_name, service in self.service_types.items():
            if not _MESSAGE_TYPE.fullmatch(type_name):
                raise located(f"service_types.{type_name}", "a service type is spelled package/Type")
            for part in ("request", "response"):
                for field, field_type in getattr(service, part).items():
                    if not _FIELD_TYPE.fullmatch(field_type):
                        raise located(
                            f"service_types.{type_name}.{part}.{field}", f"{field_type!r} is not a field type"
                        )
        return self

    @model_validator(mode="after")
    def _arm_timing_known(self) -> "RosSpec":
        carries = "$duration" in self.arm_command.template.placeholders()
        if not carries and self.arm_command.profile_time_s is None:
            raise located(
                "arm_command.profile_time_s",
                "the arm command carries no $duration, so its driver decides "
                "how long a command takes: declare that time (its stock "
                "profile), as profile_time_s",
            )
        return self

    @property
    def motion_set_by_setup(self) -> bool:
        """Whether a setup call gives the driver each motion's duration (its own time profile)."""
        return any(call.sets_motion_time for call in self.setup)

    @model_validator(mode="after")
    def _types_match_templates(self) -> "RosSpec":
        topics = {
            "joint_states": self.joint_states,
            "arm_command": self.arm_command,
            "gripper_command": self.gripper_command,
            **{f"object_poses.{name}": topic for name, topic in self.object_poses.items()},
        }
        for path, topic in topics.items():
            problem = topic.type_problem() if topic is not None else None
            if problem:
                raise located(f"{path}.type", problem)
        return self
