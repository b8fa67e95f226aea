"""The ROS messages envfactory speaks, as rosbridge JSON dicts, in both directions.

The client encodes commands and decodes states; the digital twin does the
reverse. Keeping both here means one place knows each message's shape, and
every decoder rejects a malformed message with a reason instead of guessing.
"""

from __future__ import annotations

import math

import numpy as np

from envfactory.spec.schema import ArmCommand, GripperCommand


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


def encode_joint_state(names: list[str], position, velocity, stamp: float) -> dict:
    return {"header": {"stamp": _stamp(stamp), "frame_id": ""}, "name": list(names),
            "position": [float(v) for v in position], "velocity": [float(v) for v in velocity], "effort": []}


def decode_joint_state(msg: dict, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Positions and velocities in the order of `names`, matched by name, not by index."""
    if not isinstance(msg, dict) or not isinstance(msg.get("name"), list):
        raise MalformedMessage("joint state without a 'name' list")
    received = msg["name"]
    position = _finite_floats(msg.get("position", []), "joint state position", len(received))
    raw_velocity = msg.get("velocity") or [0.0] * len(received)
    velocity = _finite_floats(raw_velocity, "joint state velocity", len(received))
    index = {name: i for i, name in enumerate(received)}
    missing = [name for name in names if name not in index]
    if missing:
        raise MalformedMessage(f"joint state lacks joints {missing}")
    order = [index[name] for name in names]
    return position[order], velocity[order]


# ------------------------------------------------------------------ object poses


def encode_pose(frame_id: str, position, quaternion, stamp: float) -> dict:
    x, y, z, w = (float(v) for v in quaternion)
    return {"header": {"stamp": _stamp(stamp), "frame_id": frame_id},
            "pose": {"position": dict(zip("xyz", (float(v) for v in position))),
                     "orientation": {"x": x, "y": y, "z": z, "w": w}}}


def decode_pose(msg: dict) -> tuple[str, np.ndarray, np.ndarray]:
    """(frame_id, position, quaternion x y z w) of a geometry_msgs/PoseStamped."""
    try:
        pose = msg["pose"]
        position = _finite_floats([pose["position"][k] for k in "xyz"], "pose position")
        quaternion = _finite_floats([pose["orientation"][k] for k in "xyzw"], "pose orientation")
        frame = str(msg.get("header", {}).get("frame_id", ""))
    except (KeyError, TypeError) as exc:
        raise MalformedMessage(f"pose lacks {exc}") from exc
    norm = np.linalg.norm(quaternion)
    if not 0.9 < norm < 1.1:
        raise MalformedMessage(f"pose orientation is not a unit quaternion (norm {norm:.3f})")
    return frame, position, quaternion / norm


# ------------------------------------------------------------------ arm commands


def encode_arm(command: ArmCommand, joints: list[str], q_target, duration: float) -> dict:
    if command.encoding == "joint_trajectory":
        return {"header": {"stamp": _stamp(0.0), "frame_id": ""}, "joint_names": list(joints),
                "points": [{"positions": [float(v) for v in q_target], "velocities": [0.0] * len(joints),
                            "accelerations": [], "effort": [], "time_from_start": _stamp(duration)}]}
    return {"name": command.group, "cmd": [float(v) for v in q_target]}


def encode_arm_stop(command: ArmCommand, joints: list[str], q_hold) -> dict | None:
    """The stop: an empty trajectory (the controller's own stop: it holds where it is), or,
    for group commands that have no such message, a command to hold at `q_hold`."""
    if command.encoding == "joint_trajectory":
        return {"header": {"stamp": _stamp(0.0), "frame_id": ""}, "joint_names": list(joints), "points": []}
    if q_hold is None:
        return None
    return {"name": command.group, "cmd": [float(v) for v in q_hold]}


def decode_arm(command: ArmCommand, joints: list[str], msg: dict, default_duration: float
               ) -> tuple[np.ndarray | None, float]:
    """(target in `joints` order or None for a stop, duration)."""
    if command.encoding == "joint_trajectory":
        points = msg.get("points")
        if not isinstance(points, list):
            raise MalformedMessage("trajectory without a 'points' list")
        if not points:
            return None, 0.0
        names = msg.get("joint_names", [])
        if sorted(names) != sorted(joints):
            raise MalformedMessage(f"trajectory joint_names {names} differ from {joints}")
        positions = _finite_floats(points[-1].get("positions"), "trajectory positions", len(names))
        by_name = dict(zip(names, positions))
        return np.array([by_name[j] for j in joints]), _duration_seconds(points[-1].get("time_from_start", {}))
    if msg.get("name") != command.group:
        raise MalformedMessage(f"group command for {msg.get('name')!r}, expected {command.group!r}")
    return _finite_floats(msg.get("cmd"), "group command", len(joints)), default_duration


# ------------------------------------------------------------------ gripper commands


def encode_gripper(command: GripperCommand, value: float) -> dict:
    if command.encoding == "float64_array":
        return {"layout": {"dim": [], "data_offset": 0}, "data": [float(value)]}
    return {"name": command.name, "cmd": float(value)}


def decode_gripper(command: GripperCommand, msg: dict) -> float:
    if command.encoding == "float64_array":
        return float(_finite_floats(msg.get("data"), "gripper command", 1)[0])
    if msg.get("name") != command.name:
        raise MalformedMessage(f"gripper command for {msg.get('name')!r}, expected {command.name!r}")
    return float(_finite_floats([msg.get("cmd")], "gripper command", 1)[0])
