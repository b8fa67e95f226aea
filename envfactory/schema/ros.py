"""A robot's topics under rosbridge; every one can be overridden in YAML or by kwarg.

Each topic's messages follow a template (envfactory.schema.messages): `encoding`
names a shipped one or writes one in place.
"""

from __future__ import annotations

import re
from typing import Annotated, Any, ClassVar

from pydantic import Field, PrivateAttr, model_validator

from envfactory.schema.base import Model, Position, Rpy, located
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

    @model_validator(mode="after")
    def _states_declared(self) -> "GripperCommand":
        holds_state = "$state" in self.template.placeholders()
        if holds_state and self.states is None:
            raise located("states", "the template holds $state: declare states: {open: ..., closed: ...}, "
                                    "what the driver takes to open and to close")
        if self.states is not None and not holds_state:
            raise located("states", "states are declared but the template has no $state placeholder")
        return self


class StaticTransform(Model):
    """Where a frame sits in its parent: lets object poses from a camera reach the task frame."""

    parent: str
    xyz: Position = (0.0, 0.0, 0.0)
    rpy: Rpy = (0.0, 0.0, 0.0)


class RosSpec(Model):
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

    @model_validator(mode="after")
    def _message_types_well_formed(self) -> "RosSpec":
        for type_name, fields in self.message_types.items():
            if not _MESSAGE_TYPE.fullmatch(type_name):
                raise located(f"message_types.{type_name}", "a message type is spelled package/Type")
            for field, field_type in fields.items():
                if not _FIELD_TYPE.fullmatch(field_type):
                    raise located(f"message_types.{type_name}.{field}",
                                  f"{field_type!r} is not a field type (a primitive such as float64 or uint8, "
                                  "a message type package/Type, either with [] for a list)")
        return self

    @model_validator(mode="after")
    def _types_match_templates(self) -> "RosSpec":
        topics = {"joint_states": self.joint_states, "arm_command": self.arm_command,
                  "gripper_command": self.gripper_command,
                  **{f"object_poses.{name}": topic for name, topic in self.object_poses.items()}}
        for path, topic in topics.items():
            problem = topic.type_problem() if topic is not None else None
            if problem:
                raise located(f"{path}.type", problem)
        return self
