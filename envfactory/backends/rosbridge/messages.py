"""The ROS messages envfactory speaks, as rosbridge JSON dicts, in both directions.

The client encodes commands and decodes states; the digital twin does the
reverse. Each message's shape is a template declared in YAML (the robot's
`ros:` map, or robots/_messages.yaml); here the values go in and come out,
and every decoder rejects a malformed message with a reason instead of guessing.
"""

from __future__ import annotations

import itertools
import math
import os
import time

import numpy as np

from envfactory.backends.rosbridge.templates import TemplateMismatch, fill, read
from envfactory.schema.messages import MessageTemplate, placeholder_paths, resolve
from envfactory.schema.models import ArmCommand, GripperCommand


class MalformedMessage(ValueError):
    """A message that does not have the shape or values its type promises."""


def _stamp(seconds: float) -> dict:
    whole = math.floor(seconds)
    return {"secs": int(whole), "nsecs": int((seconds - whole) * 1e9)}


def _duration_seconds(duration: dict) -> float:
    # ROS 1 writes secs/nsecs, ROS 2 sec/nanosec
    secs = duration.get("secs", duration.get("sec", 0))
    nsecs = duration.get("nsecs", duration.get("nanosec", 0))
    return float(secs) + float(nsecs) * 1e-9


def _finite_floats(values, what: str, count: int | None = None) -> np.ndarray:
    if isinstance(values, list) and any(v is None for v in values):
        raise MalformedMessage(f"{what} holds null (a NaN or infinity on the robot side)")
    try:
        array = np.asarray(values, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise MalformedMessage(f"{what} is not a list of numbers") from exc
    if count is not None and array.size != count:
        raise MalformedMessage(f"{what} has {array.size} values, expected {count}")
    if not np.all(np.isfinite(array)):
        raise MalformedMessage(f"{what} holds a non-finite value")
    return array


# ------------------------------------------------------------------ joint states


def _lookup(message, path: str):
    """The value at a dotted path of a message, or None."""
    for key in path.split("."):
        if isinstance(message, dict):
            message = message.get(key)
        elif isinstance(message, list) and key.isdigit() and int(key) < len(message):
            message = message[int(key)]
        else:
            return None
    return message


def encode_joint_state(
    names: list[str], position, velocity, stamp: float, template: MessageTemplate | None = None
) -> dict:
    template = template or resolve("joint_state")
    return fill(
        template.message,
        {
            "$stamp": _stamp(stamp),
            "$joint_names": list(names),
            "$positions": [float(v) for v in position],
            "$velocities": [float(v) for v in velocity],
        },
    )


def decode_joint_state(
    msg: dict, names: list[str], template: MessageTemplate | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Positions and velocities in the order of `names`, matched by name, not by index."""
    paths = placeholder_paths((template or resolve("joint_state")).message)
    received = _lookup(msg, paths["$joint_names"]) if isinstance(msg, dict) else None
    if not isinstance(received, list):
        raise MalformedMessage(f"joint state without a '{paths['$joint_names']}' list")
    position = _finite_floats(_lookup(msg, paths["$positions"]) or [], "joint state position", len(received))
    raw_velocity = (_lookup(msg, paths["$velocities"]) if "$velocities" in paths else None) or [0.0] * len(received)
    velocity = _finite_floats(raw_velocity, "joint state velocity", len(received))
    index = {name: i for i, name in enumerate(received)}
    missing = [name for name in names if name not in index]
    if missing:
        raise MalformedMessage(f"joint state lacks joints {missing}")
    order = [index[name] for name in names]
    return position[order], velocity[order]


# ------------------------------------------------------------------ object poses

_POSITION, _ORIENTATION = ("$x", "$y", "$z"), ("$qx", "$qy", "$qz", "$qw")


def encode_pose(frame_id: str, position, quaternion, stamp: float, template: MessageTemplate | None = None) -> dict:
    template = template or resolve("pose_stamped")
    values = {"$stamp": _stamp(stamp), "$frame_id": frame_id}
    values.update(zip(_POSITION, (float(v) for v in position)))
    values.update(zip(_ORIENTATION, (float(v) for v in quaternion)))
    return fill(template.message, values)


def decode_pose(msg: dict, template: MessageTemplate | None = None) -> tuple[str, np.ndarray, np.ndarray]:
    """(frame_id, position, quaternion x y z w) of a pose message."""
    try:
        values = read((template or resolve("pose_stamped")).message, msg)
    except TemplateMismatch as exc:
        raise MalformedMessage(f"pose {exc}") from None
    position = _finite_floats([values[k] for k in _POSITION], "pose position")
    quaternion = _finite_floats([values[k] for k in _ORIENTATION], "pose orientation")
    frame = str(values.get("$frame_id", ""))
    norm = np.linalg.norm(quaternion)
    if not 0.9 < norm < 1.1:
        raise MalformedMessage(f"pose orientation is not a unit quaternion (norm {norm:.3f})")
    return frame, position, quaternion / norm


# ------------------------------------------------------------------ arm commands


def _arm_values(command: ArmCommand, joints: list[str], q, duration: float) -> dict:
    return {
        "$joint_names": list(joints),
        "$positions": None if q is None else [float(v) for v in q],
        "$zeros": [0.0] * len(joints),
        "$duration": _stamp(duration),
        "$group": command.group,
    }


def carries_duration(command: ArmCommand) -> bool:
    """Whether the arm command says how long the motion takes (else the driver decides)."""
    return "$duration" in command.template.placeholders()


def encode_arm(command: ArmCommand, joints: list[str], q_target, duration: float) -> dict:
    return fill(command.template.message, _arm_values(command, joints, q_target, duration))


def encode_arm_stop(command: ArmCommand, joints: list[str], q_hold) -> dict | None:
    """The stop: the template's stop message (a trajectory controller's own stop: it holds where it
    is), or, for commands that have none, a command to hold at `q_hold` (None if there is nothing to hold)."""
    template = command.template
    if template.stop is not None and "$positions" not in template.placeholders("stop"):
        return fill(template.stop, _arm_values(command, joints, None, 0.0))
    if q_hold is None:
        return None
    return fill(template.stop or template.message, _arm_values(command, joints, q_hold, 0.0))


def decode_arm(
    command: ArmCommand, joints: list[str], msg: dict, default_duration: float
) -> tuple[np.ndarray | None, float]:
    """(target in `joints` order or None for a stop, duration)."""
    template = command.template
    try:
        values = read(template.message, msg)
    except TemplateMismatch as exc:
        if template.stop is None:
            raise MalformedMessage(f"arm command {exc}") from None
        try:  # a stop is told from a command by its fixed values
            values = read(template.stop, msg, exact=True)
        except TemplateMismatch:
            raise MalformedMessage(f"arm command {exc}") from None
        if "$positions" not in values:
            return None, 0.0
    if "$group" in values and values["$group"] != command.group:
        raise MalformedMessage(f"group command for {values['$group']!r}, expected {command.group!r}")
    names = values.get("$joint_names", list(joints))
    if not isinstance(names, list) or sorted(names) != sorted(joints):
        raise MalformedMessage(f"arm command joint names {names} differ from {joints}")
    positions = _finite_floats(values["$positions"], "arm command positions", len(names))
    by_name = dict(zip(names, positions))
    duration = _duration_seconds(values["$duration"]) if isinstance(values.get("$duration"), dict) else default_duration
    return np.array([by_name[j] for j in joints]), duration


# ------------------------------------------------------------------ gripper commands


_goal_ids = itertools.count()


def new_goal_id() -> str:
    """A goal_id unique across processes and time, as actionlib clients make them."""
    return f"envfactory-{os.getpid()}-{next(_goal_ids)}-{time.time_ns()}"


def gripper_state(command: GripperCommand, value: float, open_value: float, closed_value: float):
    """What an open/close driver takes for a gripper position: the end the value is nearer (a value halfway
    opens: the safer side for whatever the jaws hold is not knowable here); None for a position driver."""
    if command.states is None:
        return None
    closes = abs(value - closed_value) < abs(value - open_value)
    return command.states.closed if closes else command.states.open


def encode_gripper(
    command: GripperCommand, value: float, open_value: float, closed_value: float, goal_id: str | None = None
) -> dict:
    """The command for a gripper position, in the driver's units (`command.scale` times the joint value)."""
    values = {
        "$value": float(value) * command.scale,
        "$name": command.name,
        "$goal_id": goal_id or new_goal_id(),
        "$state": gripper_state(command, value, open_value, closed_value),
    }
    return fill(command.template.message, values)


def decode_gripper(command: GripperCommand, msg: dict, open_value: float, closed_value: float) -> float:
    """The gripper position a command asks for (an open/close driver's: the open or the closed end)."""
    try:
        values = read(command.template.message, msg)
    except TemplateMismatch as exc:
        raise MalformedMessage(f"gripper command {exc}") from None
    if "$name" in values and values["$name"] != command.name:
        raise MalformedMessage(f"gripper command for {values['$name']!r}, expected {command.name!r}")
    if command.states is not None:
        state = values["$state"]
        if state == command.states.open and type(state) is type(command.states.open):
            return float(open_value)
        if state == command.states.closed and type(state) is type(command.states.closed):
            return float(closed_value)
        raise MalformedMessage(
            f"gripper command state {state!r} is neither open ({command.states.open!r}) "
            f"nor closed ({command.states.closed!r})"
        )
    return float(_finite_floats([values["$value"]], "gripper command", 1)[0]) / command.scale


# ------------------------------------------------------------------ action results (actionlib)

# actionlib_msgs/GoalStatus.status, by value
GOAL_STATUS = {
    0: "PENDING",
    1: "ACTIVE",
    2: "PREEMPTED",
    3: "SUCCEEDED",
    4: "ABORTED",
    5: "REJECTED",
    6: "PREEMPTING",
    7: "RECALLING",
    8: "RECALLED",
    9: "LOST",
}
SUCCEEDED = 3


def decode_action_result(msg: dict) -> tuple[str, int, str]:
    """(goal id, status, what the driver said) of an actionlib ActionResult: its GoalStatus and the text of the
    result's own fields."""
    status = msg.get("status") if isinstance(msg, dict) else None
    goal = status.get("goal_id") if isinstance(status, dict) else None
    if not isinstance(goal, dict) or not isinstance(goal.get("id"), str) or not isinstance(status.get("status"), int):
        raise MalformedMessage("action result without status.goal_id.id and status.status")
    said = [str(status.get("text") or "")]
    result = msg.get("result")
    if isinstance(result, dict) and result:
        said.append(", ".join(f"{key} {value!r}" for key, value in result.items()))
    return goal["id"], status["status"], "; ".join(part for part in said if part)


def encode_action_result(goal_id: str, status: int, text: str, result: dict, stamp: float) -> dict:
    """An actionlib ActionResult (the twin's drivers answer their goals with it)."""
    return {
        "header": {"seq": 0, "stamp": _stamp(stamp), "frame_id": ""},
        "status": {"goal_id": {"stamp": _stamp(stamp), "id": goal_id}, "status": status, "text": text},
        "result": result,
    }
