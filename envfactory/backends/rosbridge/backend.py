"""The real robot over rosbridge (roslibpy, asyncio transport), behind the same Backend
protocol as the simulator.

Every doubt stops the arm. Before anything is published the motion gate is
checked again, and the joint states (and the poses of the task's objects)
must be fresh by local receive time and well formed. A stale or malformed
reading ends the episode with the reason and a stop. A deadman stops the arm
when commands cease, and close() always sends the stop. Each arm command is
a trajectory of bounded duration, so a robot that loses this client comes to
rest at the end of the last segment on its own.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from envfactory.backends.base import BackendError, EpisodeAbort, JointReading, MotionRefused, ObjectReading
from envfactory.backends.rosbridge import messages
from envfactory.backends.rosbridge.transforms import FrameGraph
from envfactory.spec.schema import EnvSpec

log = logging.getLogger("envfactory.rosbridge")

MOTION_ENV_VAR = "ALLOW_REAL_ROBOT_MOTION"
POLL_S = 0.02
# reconnect backoff: roslibpy waits INITIAL, then FACTOR times longer each try, at most MAX
RECONNECT_INITIAL_S, RECONNECT_FACTOR, RECONNECT_MAX_S = 0.25, 2.0, 2.0


def motion_allowed(flag: bool) -> bool:
    return flag or os.environ.get(MOTION_ENV_VAR, "") == "1"


def require_motion_gate(flag: bool, what: str) -> None:
    if not motion_allowed(flag):
        raise MotionRefused(
            f"{what}: real-robot motion is not allowed. Pass allow_real_robot_motion=True, set "
            f"{MOTION_ENV_VAR}=1, or use the CLI's --allow-real-robot-motion once the workspace is clear."
        )


@dataclass
class _Latest:
    """The newest good reading of one topic, and what went wrong since, if anything."""

    values: tuple | None = None
    received: float = 0.0  # time.monotonic() at receipt
    error: str = ""


class RosbridgeBackend:
    teleports_on_reset = False  # the arm drives home
    def __init__(self, spec: EnvSpec, urdf_path: Path, task_origin_world: np.ndarray, render_mode: str | None = None):
        robot, real = spec.robot, spec.env.real
        self.spec, self.real = spec, real
        if robot.ros is None:
            raise BackendError(f"robot {robot.name!r} declares no 'ros:' topic map in its YAML")
        if real.auto_launch_cube_tracker:
            raise BackendError("auto_launch_cube_tracker=True: envfactory does not launch trackers. Start the "
                               f"{real.cube_tracker_camera} cube tracker yourself, then make the env with it False.")
        if spec.env.use_kinect:
            raise BackendError("use_kinect renders a simulated camera; a real robot has none to render")
        if render_mode == "human":
            raise BackendError("render_mode='human' opens a simulator window; a real robot has none")
        self.allow_motion = real.allow_motion
        require_motion_gate(self.allow_motion, f"refusing to connect to {robot.name!r}")
        self.ros_spec = robot.ros
        self.state_names = robot.state_names
        self.arm_names = robot.arm_state_names
        self._arm_in_states = robot.arm_state_indices
        missing = [name for name in spec.task.objects if name not in self.ros_spec.object_poses]
        if missing:
            raise BackendError(f"robot {robot.name!r}: ros.object_poses has no topic for {missing}")
        self.frames = FrameGraph(self.ros_spec.task_frame_id, self.ros_spec.static_transforms)
        target = real.cube_tracker_target_frame
        if target and not self.ros_spec.use_tf:
            try:
                self.frames.to_task(target, np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
            except KeyError as exc:
                raise BackendError(f"cube_tracker_target_frame {target!r}: {exc.args[0]}; declare it in "
                                   f"ros.static_transforms or set ros.use_tf") from None

        self._lock = threading.Lock()
        self._joints = _Latest()
        self._objects = {name: _Latest() for name in spec.task.objects}
        self._last_command = 0.0
        self._deadman_armed = False
        self._closed = False
        self._connect()
        try:
            self._wait_for_first_readings()
        except BackendError:
            self._shutdown_connection()
            raise
        self._deadman = threading.Thread(target=self._watch_deadman, name="envfactory-deadman", daemon=True)
        self._deadman.start()

    # ------------------------------------------------------------------ connection

    @property
    def url(self) -> str:
        return f"ws://{self.real.host}:{self.real.port}"

    def _connect(self) -> None:
        import roslibpy

        self.ros = roslibpy.Ros(self.real.host, self.real.port, transport="asyncio")
        factory = self.ros.factory
        # roslibpy retries forever by default; a bounded, backed-off retry never hangs a run
        factory.maxRetries = self.real.reconnect_tries
        factory.initialDelay, factory.maxDelay, factory.factor = RECONNECT_INITIAL_S, RECONNECT_MAX_S, RECONNECT_FACTOR
        try:
            self.ros.run(timeout=self.real.connect_timeout_s)
        except Exception as exc:
            self._shutdown_connection()
            raise BackendError(f"could not reach rosbridge at {self.url} within {self.real.connect_timeout_s:g} s "
                               f"({exc}): is rosbridge_server running?") from None
        ros_spec = self.ros_spec
        self._joint_topic = roslibpy.Topic(self.ros, ros_spec.joint_states.topic, ros_spec.joint_states.type)
        self._joint_topic.subscribe(self._on_joint_state)
        self._object_topics = {}
        for name in self._objects:
            topic_spec = ros_spec.object_poses[name]
            topic = roslibpy.Topic(self.ros, topic_spec.topic, topic_spec.type)
            topic.subscribe(lambda msg, name=name: self._on_pose(name, msg))
            self._object_topics[name] = topic
        if ros_spec.use_tf:
            for name in ("/tf", "/tf_static"):
                roslibpy.Topic(self.ros, name, "tf2_msgs/TFMessage").subscribe(self.frames.learn)
        self._arm_topic = roslibpy.Topic(self.ros, ros_spec.arm_command.topic, ros_spec.arm_command.type)
        self._arm_topic.advertise()
        self._gripper_topic = None
        if ros_spec.gripper_command is not None:
            gripper = ros_spec.gripper_command
            self._gripper_topic = roslibpy.Topic(self.ros, gripper.topic, gripper.type)
            self._gripper_topic.advertise()

    def _shutdown_connection(self) -> None:
        try:
            self.ros.close(timeout=1.0)
        except Exception:  # closing a dead connection: nothing left to tell it
            pass

    def _await_connection(self) -> None:
        """roslibpy reconnects in the background with backoff; wait a bounded time for it."""
        if self.ros.is_connected:
            return
        budget = sum(min(RECONNECT_INITIAL_S * RECONNECT_FACTOR**i, RECONNECT_MAX_S)
                     for i in range(self.real.reconnect_tries)) + 1.0
        deadline = time.monotonic() + budget
        while time.monotonic() < deadline:
            if self.ros.is_connected:
                return
            time.sleep(POLL_S)
        raise BackendError(f"lost the rosbridge connection to {self.url}; {self.real.reconnect_tries} reconnect "
                           f"tries over {budget:.1f} s failed. The arm stops at the end of its last segment.")

    # ------------------------------------------------------------------ readings

    def _on_joint_state(self, msg: dict) -> None:
        now = time.monotonic()
        try:
            values = messages.decode_joint_state(msg, self.state_names)
        except messages.MalformedMessage as exc:
            with self._lock:
                self._joints.error = f"malformed message on {self.ros_spec.joint_states.topic}: {exc}"
            return
        with self._lock:
            self._joints.values, self._joints.received = values, now

    def _on_pose(self, name: str, msg: dict) -> None:
        now = time.monotonic()
        topic = self.ros_spec.object_poses[name].topic
        try:
            frame, position, quaternion = messages.decode_pose(msg)
            position, quaternion = self.frames.to_task(frame, position, quaternion)
        except (messages.MalformedMessage, KeyError) as exc:
            with self._lock:
                self._objects[name].error = f"unusable message on {topic}: {exc}"
            return
        with self._lock:
            self._objects[name].values, self._objects[name].received = (position, quaternion), now

    def _fresh(self, latest: _Latest, topic: str, limit: float) -> tuple[tuple, float]:
        """The newest values and their receive time, or EpisodeAbort (after a stop) saying why
        they cannot be trusted."""
        with self._lock:
            values, received, error = latest.values, latest.received, latest.error
        reason = error
        if not reason and values is None:
            reason = f"nothing received on {topic} yet"
        if not reason:
            age = time.monotonic() - received
            if age > limit:
                reason = f"{topic} is stale: newest message {age:.2f} s old (limit {limit:g} s)"
        if reason:
            self.stop()
            raise EpisodeAbort(reason)
        return values, received

    def _fresh_joints(self) -> tuple[tuple[np.ndarray, np.ndarray], float]:
        return self._fresh(self._joints, self.ros_spec.joint_states.topic, self.real.joint_state_timeout_s)

    def _fresh_object(self, name: str) -> tuple[tuple[np.ndarray, np.ndarray], float]:
        return self._fresh(self._objects[name], self.ros_spec.object_poses[name].topic, self.real.cube_pose_timeout_s)

    def _check_inputs(self) -> None:
        self._fresh_joints()
        for name in self._objects:
            self._fresh_object(name)

    # ------------------------------------------------------------------ commands

    def _publish(self, topic, msg: dict) -> None:
        require_motion_gate(self.allow_motion, "refusing to publish a command")
        if not self.ros.is_connected:
            raise BackendError(f"lost the rosbridge connection to {self.url}: command not sent")
        import roslibpy

        topic.publish(roslibpy.Message(msg))
        with self._lock:
            self._last_command = time.monotonic()

    def command_joints(self, q_arm_target, duration: float) -> None:
        self._check_inputs()
        msg = messages.encode_arm(self.ros_spec.arm_command, self.arm_names, q_arm_target, duration)
        self._publish(self._arm_topic, msg)
        self._deadman_armed = True

    def command_gripper(self, value: float) -> None:
        if self._gripper_topic is None:
            raise BackendError(f"robot {self.spec.robot.name!r} declares no ros.gripper_command")
        self._check_inputs()
        self._publish(self._gripper_topic, messages.encode_gripper(self.ros_spec.gripper_command, value))

    def stop(self) -> None:
        """Hold the arm where it is. Allowed with the gate closed: stopping is not motion."""
        self._deadman_armed = False
        with self._lock:
            values = self._joints.values
        q_hold = values[0][self._arm_in_states] if values is not None else None
        msg = messages.encode_arm_stop(self.ros_spec.arm_command, self.arm_names, q_hold)
        if msg is None or not self.ros.is_connected:
            log.warning("cannot send the stop (%s); the arm halts at the end of its last segment",
                        "no joint state to hold" if msg is None else "not connected")
            return
        import roslibpy

        self._arm_topic.publish(roslibpy.Message(msg))

    def _watch_deadman(self) -> None:
        while not self._closed:
            time.sleep(POLL_S * 2)
            with self._lock:
                silent = time.monotonic() - self._last_command
            if self._deadman_armed and silent > self.real.deadman_s:
                log.warning("deadman: no command for %.2f s, stopping the arm", silent)
                self.stop()

    # ------------------------------------------------------------------ protocol

    def reset(self, q_arm, gripper, objects) -> None:
        """Drive home slowly and wait there; the objects stay where the user put them."""
        self._deadman_armed = False
        self._await_connection()
        with self._lock:  # a fault of the last episode must be seen afresh to count again
            self._joints.error = ""
            for latest in self._objects.values():
                latest.error = ""
        self._wait_for_first_readings()
        (position, _), _ = self._fresh_joints()
        home = np.asarray(q_arm, float)
        distance = float(np.max(np.abs(position[self._arm_in_states] - home)))
        duration = max(1.0, distance / self.real.reset_speed)
        self._publish(self._arm_topic, messages.encode_arm(self.ros_spec.arm_command, self.arm_names, home, duration))
        if gripper is not None and self._gripper_topic is not None:
            self._publish(self._gripper_topic, messages.encode_gripper(self.ros_spec.gripper_command, gripper))
        deadline = time.monotonic() + max(self.real.reset_timeout_s, duration + 2.0)
        while True:
            (position, _), _ = self._fresh_joints()
            if np.max(np.abs(position[self._arm_in_states] - home)) < self.real.reset_tolerance:
                break
            if time.monotonic() > deadline:
                self.stop()
                raise BackendError(f"the arm did not reach home within {deadline:.0f} s of the reset command")
            time.sleep(POLL_S)
        for name in self._objects:
            self._fresh_object(name)

    def _wait_for_first_readings(self) -> None:
        wait = self.real.connect_timeout_s
        deadline = time.monotonic() + wait
        while time.monotonic() < deadline:
            with self._lock:
                silent = [self.ros_spec.joint_states.topic] if self._joints.values is None else []
                silent += [self.ros_spec.object_poses[name].topic for name, latest in self._objects.items()
                           if latest.values is None]
            if not silent:
                return
            time.sleep(POLL_S)
        raise BackendError(f"connected to {self.url}, but nothing arrived on {silent} within {wait:g} s: "
                           f"is the robot driver (and the cube tracker) running?")

    def advance(self, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            if not self.ros.is_connected:
                raise BackendError(f"lost the rosbridge connection to {self.url} during the step")
            time.sleep(min(POLL_S, max(0.0, deadline - time.monotonic())))

    def read_joints(self) -> JointReading:
        (position, velocity), stamp = self._fresh_joints()
        return JointReading(position.copy(), velocity.copy(), stamp)

    def read_object(self, name: str) -> ObjectReading:
        (position, quaternion), stamp = self._fresh_object(name)
        return ObjectReading(position.copy(), quaternion.copy(), stamp)

    def mark_goal(self, position) -> None:
        pass  # nothing to draw on hardware

    def render(self, width: int = 480, height: int = 360) -> np.ndarray:
        raise BackendError("a real robot has no rendered view; record it with a camera of your own")

    def capture(self, camera):
        raise BackendError("a real robot has no simulated camera")

    def close(self) -> None:
        if self._closed:
            return
        try:
            self.stop()
        finally:
            self._closed = True
            self._shutdown_connection()
