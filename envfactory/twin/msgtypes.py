"""The ROS 1 core message and service types the twin knows, and the checks a rosbridge
server makes when it turns JSON into a typed message and back. A driver's own message
types are robot knowledge: they come from the robot's `ros.message_types`.

A rosbridge server fills a typed message from the JSON a client sends: a key the
type lacks, or a value of the wrong kind (a string for a float, null for a
number, a number for a list), is refused; a field left out keeps its default.
Going out, NaN and infinity have no JSON spelling and are sent as null.
"""

from __future__ import annotations

import math

# field -> type; "T[]" is a list of T; primitives are the ROS 1 built-ins
MESSAGES: dict[str, dict[str, str]] = {
    "std_msgs/Header": {"seq": "uint32", "stamp": "time", "frame_id": "string"},
    "std_msgs/MultiArrayDimension": {"label": "string", "size": "uint32", "stride": "uint32"},
    "std_msgs/MultiArrayLayout": {"dim": "std_msgs/MultiArrayDimension[]", "data_offset": "uint32"},
    "std_msgs/Float64MultiArray": {"layout": "std_msgs/MultiArrayLayout", "data": "float64[]"},
    "std_msgs/Float64": {"data": "float64"},
    "std_msgs/String": {"data": "string"},
    "sensor_msgs/JointState": {
        "header": "std_msgs/Header",
        "name": "string[]",
        "position": "float64[]",
        "velocity": "float64[]",
        "effort": "float64[]",
    },
    "trajectory_msgs/JointTrajectoryPoint": {
        "positions": "float64[]",
        "velocities": "float64[]",
        "accelerations": "float64[]",
        "effort": "float64[]",
        "time_from_start": "duration",
    },
    "trajectory_msgs/JointTrajectory": {
        "header": "std_msgs/Header",
        "joint_names": "string[]",
        "points": "trajectory_msgs/JointTrajectoryPoint[]",
    },
    "geometry_msgs/Point": {"x": "float64", "y": "float64", "z": "float64"},
    "geometry_msgs/Vector3": {"x": "float64", "y": "float64", "z": "float64"},
    "geometry_msgs/Quaternion": {"x": "float64", "y": "float64", "z": "float64", "w": "float64"},
    "geometry_msgs/Pose": {"position": "geometry_msgs/Point", "orientation": "geometry_msgs/Quaternion"},
    "geometry_msgs/PoseStamped": {"header": "std_msgs/Header", "pose": "geometry_msgs/Pose"},
    "geometry_msgs/Transform": {"translation": "geometry_msgs/Vector3", "rotation": "geometry_msgs/Quaternion"},
    "geometry_msgs/TransformStamped": {
        "header": "std_msgs/Header",
        "child_frame_id": "string",
        "transform": "geometry_msgs/Transform",
    },
    "tf2_msgs/TFMessage": {"transforms": "geometry_msgs/TransformStamped[]"},
    "actionlib_msgs/GoalID": {"stamp": "time", "id": "string"},
    "actionlib_msgs/GoalStatus": {"goal_id": "actionlib_msgs/GoalID", "status": "uint8", "text": "string"},
    "actionlib_msgs/GoalStatusArray": {"header": "std_msgs/Header", "status_list": "actionlib_msgs/GoalStatus[]"},
}

# rosapi's topic services: request fields, response fields
SERVICES: dict[str, tuple[dict[str, str], dict[str, str]]] = {
    "rosapi/TopicType": ({"topic": "string"}, {"type": "string"}),
    "rosapi/Subscribers": ({"topic": "string"}, {"subscribers": "string[]"}),
    "rosapi/Publishers": ({"topic": "string"}, {"publishers": "string[]"}),
    "rosapi/Topics": ({}, {"topics": "string[]", "types": "string[]"}),
    "rosapi/TopicsForType": ({"type": "string"}, {"topics": "string[]"}),
}

_INTEGERS = {"int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64", "byte", "char"}
_FLOATS = {"float32", "float64"}
_STAMPS = {"time", "duration"}


class FieldError(ValueError):
    """The JSON does not fill the type: a missing field type, a wrong kind of value."""


PRIMITIVES = _INTEGERS | _FLOATS | _STAMPS | {"bool", "string"}


def with_driver_types(declared: dict[str, dict[str, str]]) -> dict[str, dict[str, str]]:
    """The core types and a driver's own (a robot's `ros.message_types`), every field type resolvable;
    else FieldError naming the type and field."""
    types = {**MESSAGES, **declared}
    for type_name, fields in declared.items():
        for field, field_type in fields.items():
            element = field_type.split("[")[0]
            if element not in PRIMITIVES and element not in types:
                raise FieldError(f"{type_name}.{field}: unknown field type {field_type!r}")
    return types


def known(type_name: str, types: dict[str, dict[str, str]] = MESSAGES) -> bool:
    return type_name in types


def check(type_name: str, value, path: str = "", types: dict[str, dict[str, str]] = MESSAGES) -> None:
    """Raise FieldError naming the first field that `value` cannot fill as `type_name`."""
    where = path or "the message"
    if type_name.endswith("]"):
        if not isinstance(value, list):
            raise FieldError(f"{where} must be a list ({type_name}), got {_kind(value)}")
        for i, item in enumerate(value):
            check(type_name[: type_name.index("[")], item, f"{path}[{i}]", types)
        return
    if type_name in _FLOATS:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise FieldError(f"{where} must be a number ({type_name}), got {_kind(value)}")
        return
    if type_name in _INTEGERS:
        if isinstance(value, bool) or not isinstance(value, int):
            raise FieldError(f"{where} must be an integer ({type_name}), got {_kind(value)}")
        return
    if type_name == "bool":
        if not isinstance(value, bool):
            raise FieldError(f"{where} must be true or false, got {_kind(value)}")
        return
    if type_name == "string":
        if not isinstance(value, str):
            raise FieldError(f"{where} must be a string, got {_kind(value)}")
        return
    fields = {"secs": "int32", "nsecs": "int32"} if type_name in _STAMPS else types.get(type_name)
    if fields is None:
        raise FieldError(f"{type_name} is not a type this server knows")
    check_fields(type_name, fields, value, path, types)


def check_fields(
    type_name: str, fields: dict[str, str], value, path: str = "", types: dict[str, dict[str, str]] = MESSAGES
) -> None:
    """Every key of the object `value` is one of `fields` and fills it."""
    if not isinstance(value, dict):
        raise FieldError(f"{path or 'the message'} must be an object ({type_name}), got {_kind(value)}")
    for key, item in value.items():
        if key not in fields:
            raise FieldError(f"{type_name} has no field {key!r}" + (f" (at {path})" if path else ""))
        check(fields[key], item, f"{path}.{key}" if path else key, types)


def nulls_for_non_finite(value):
    """What goes on the wire: NaN and infinity become null, as JSON has no spelling for them."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {key: nulls_for_non_finite(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [nulls_for_non_finite(item) for item in value]
    return value


def _kind(value) -> str:
    if value is None:
        return "null"
    return {
        bool: "a boolean",
        int: "an integer",
        float: "a number",
        str: "a string",
        list: "a list",
        dict: "an object",
    }.get(type(value), type(value).__name__)
