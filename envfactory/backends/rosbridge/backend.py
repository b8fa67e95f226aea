"""The real robot over rosbridge (roslibpy, asyncio transport), behind the same Backend
protocol as the simulator.

Every doubt stops the arm. Before anything is published the motion gate is
checked again, and the joint states (and the poses of the task's objects)
must be fresh by local receive time and well formed. A stale or malformed
reading, a lost connection, or an arm that does not follow its command ends
the episode with the reason and one stop. A deadman stops the arm when
commands cease, and close() sends the stop. Each arm command is a motion of
bounded length, so a robot that loses this client comes to rest at the end of
the last one on its own. reset() first recovers from whatever went wrong:
it reconnects (bounded), clears the fault and waits for fresh readings.
"""

from __future__ import annotations

import logging
import math
import os
import threading
import time
from pathlib import Path

import numpy as np

from envfactory.backends.base import (
    BackendError,
    ConnectionLost,
    JointReading,
    MalformedFeed,
    MotionRefused,
    ObjectReading,
    StaleFeed,
)
from envfactory.backends.rosbridge import messages
from envfactory.backends.rosbridge.feeds import Feed, duration
from envfactory.backends.rosbridge.follow import FollowWatch
from envfactory.backends.rosbridge.link import Link
from envfactory.backends.rosbridge.transforms import FrameGraph
from envfactory.schema.models import EnvSpec

log = logging.getLogger("envfactory.rosbridge")

MOTION_ENV_VAR = "ALLOW_REAL_ROBOT_MOTION"
POLL_S = 0.02
FIRST_CONNECT_TRIES = 3  # at construction: a robot that is not there is said so quickly
# a group command (xs_sdk) carries no duration: the drive home goes out as segments this
# long, each at most reset_speed x RESET_SEGMENT_S further than the last
RESET_SEGMENT_S = 0.2


def motion_allowed(flag: bool) -> bool:
    return flag or os.environ.get(MOTION_ENV_VAR, "") == "1"


def require_motion_gate(flag: bool, what: str) -> None:
    if not motion_allowed(flag):
        raise MotionRefused(
            f"{what}: real-robot motion is not allowed. Pass allow_real_robot_motion=True, set "
            f"{MOTION_ENV_VAR}=1, or use the CLI's --allow-real-robot-motion once the workspace is clear."
        )


class RosbridgeBackend:
    teleports_on_reset = False  # the arm drives home

    def __init__(self, spec: EnvSpec, urdf_path: Path, task_frame, render_mode: str | None = None):
        robot, real = spec.robot, spec.env.real
        self.spec, self.real = spec, real
        if robot.ros is None:
            raise BackendError(f"robot {robot.name!r} declares no 'ros:' topic map in its YAML")
        if real.auto_launch_cube_tracker:
            raise BackendError("auto_launch_cube_tracker=True: envfactory does not launch trackers. Start the "
                               f"{real.cube_tracker_camera} cube tracker yourself, then make the env with it False.")
        if spec.env.observation.camera_images:
            raise BackendError("use_kinect renders a simulated camera; a real robot has none to render")
        if render_mode == "human":
            raise BackendError("render_mode='human' opens a simulator window; a real robot has none")
        self.allow_motion = real.allow_motion
        require_motion_gate(self.allow_motion, f"refusing to connect to {robot.name!r}")
        self.ros_spec = ros = robot.ros
        self.state_names = robot.state_names
        self.arm_names = robot.arm_state_names
        self._arm_in_states = robot.arm_state_indices
        missing = [name for name in spec.task.objects if name not in ros.object_poses]
        if missing:
            raise BackendError(f"robot {robot.name!r}: ros.object_poses has no topic for {missing}")
        self.frames = FrameGraph(ros.task_frame_id, ros.static_transforms)
        target = real.cube_tracker_target_frame
        if target and not ros.use_tf:
            try:
                self.frames.to_task(target, np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
            except KeyError as exc:
                raise BackendError(f"cube_tracker_target_frame {target!r}: {exc.args[0]}; declare it in "
                                   f"ros.static_transforms or set ros.use_tf") from None

        self._lock = threading.Lock()
        self.joints = Feed(ros.joint_states.topic, real.joint_state_timeout_s, self._lock)
        self.objects = {name: Feed(ros.object_poses[name].topic, real.cube_pose_timeout_s, self._lock)
                        for name in spec.task.objects}
        self.follow = FollowWatch(ros.arm_command.topic, real.follow_timeout_s)
        self._reading_age, self._reading_repeated, self._last_stamp = math.nan, False, -math.inf
        self._last_command = 0.0
        self._last_target: np.ndarray | None = None
        self._deadman_armed = False
        self._holding = False  # a stop went out and no motion since: another stop adds nothing
        self._stop_owed = False  # a stop that found no connection goes out once there is one
        self._closed = False
        subscriptions = {ros.joint_states.topic: (ros.joint_states.type, self._on_joint_state)}
        for name in self.objects:
            topic = ros.object_poses[name]
            subscriptions[topic.topic] = (topic.type, lambda msg, name=name: self._on_pose(name, msg))
        if ros.use_tf:
            for name in ("/tf", "/tf_static"):
                subscriptions[name] = ("tf2_msgs/TFMessage", self.frames.learn)
        self.link = Link(real, ros, subscriptions)
        self.link.open(FIRST_CONNECT_TRIES)
        try:
            self._wait_for_readings(since=-math.inf)
        except BackendError:
            self.link.close()
            raise
        self._deadman = threading.Thread(target=self._watch_deadman, name="envfactory-deadman", daemon=True)
        self._deadman.start()

    @property
    def url(self) -> str:
        return self.link.url

    def attach_geometry(self, collision) -> None:
        """The real arm's motions are its own: nothing to play without dynamics."""

    @property
    def _feeds(self) -> list[Feed]:
        return [self.joints, *self.objects.values()]

    # ------------------------------------------------------------------ readings

    def _on_joint_state(self, msg: dict) -> None:
        try:
            values = messages.decode_joint_state(msg, self.state_names, self.ros_spec.joint_states.template)
        except messages.MalformedMessage as exc:
            self.joints.fail(f"malformed message on {self.joints.topic}: {exc}")
            return
        self.joints.update(values)
        self.follow.observe(values[0][self._arm_in_states], time.monotonic())

    def _on_pose(self, name: str, msg: dict) -> None:
        feed = self.objects[name]
        try:
            frame, position, quaternion = messages.decode_pose(msg, self.ros_spec.object_poses[name].template)
            position, quaternion = self.frames.to_task(frame, position, quaternion)
        except messages.MalformedMessage as exc:
            feed.fail(f"malformed message on {feed.topic}: {exc}")
            return
        except KeyError as exc:
            feed.fail(f"unusable pose on {feed.topic}: {exc.args[0]}")
            return
        feed.update((position, quaternion))

    def _guarded(self, check):
        """Run a check; any fault it finds stops the arm before it propagates."""
        try:
            if not self.link.connected:
                raise ConnectionLost(f"lost the rosbridge connection to {self.url}")
            return check()
        except BackendError:
            self.stop()
            raise

    def _fresh(self, feed: Feed) -> tuple[tuple, float]:
        return self._guarded(feed.fresh)

    def _check_follow(self) -> None:
        self._guarded(lambda: self.follow.check(time.monotonic()))

    def _check_inputs(self) -> np.ndarray:
        """Everything a command relies on; returns the arm's position."""
        (position, _), _ = self._fresh(self.joints)
        for feed in self.objects.values():
            self._fresh(feed)
        self._check_follow()
        return position[self._arm_in_states]

    def _wait_for_readings(self, since: float) -> None:
        """Until every feed has a good reading newer than `since`, within connect_timeout_s."""
        wait = self.real.connect_timeout_s
        deadline = time.monotonic() + wait
        while True:
            if not self.link.connected:
                raise ConnectionLost(f"lost the rosbridge connection to {self.url} while waiting for readings")
            for feed in self._feeds:
                with self._lock:
                    error = feed.error
                if error:
                    raise MalformedFeed(error)
            silent = [feed.topic for feed in self._feeds if not feed.newer_than(since)]
            if not silent:
                return
            if time.monotonic() > deadline:
                break
            time.sleep(POLL_S)
        raise StaleFeed(f"connected to {self.url}, but nothing {'new ' if since > -math.inf else ''}arrived on "
                        f"{silent} within {duration(wait)}: is the robot driver (and the cube tracker) running?")

    # ------------------------------------------------------------------ commands

    def _publish(self, topic: str, msg: dict) -> None:
        require_motion_gate(self.allow_motion, "refusing to publish a command")
        self.link.publish(topic, msg)
        with self._lock:
            self._last_command = time.monotonic()
            self._holding = False

    def _command_arm(self, q_from: np.ndarray, q_target, duration_s: float) -> None:
        target = np.asarray(q_target, float)
        msg = messages.encode_arm(self.ros_spec.arm_command, self.arm_names, target, duration_s)
        self._guarded(lambda: self._publish(self.ros_spec.arm_command.topic, msg))
        self._last_target = target
        self.follow.commanded(q_from, target, time.monotonic())

    def command_joints(self, q_arm_target, duration: float) -> None:
        here = self._check_inputs()
        self._command_arm(here, q_arm_target, duration)
        self._deadman_armed = True

    def _gripper_message(self, value: float) -> dict:
        ends = self.spec.robot.gripper
        return messages.encode_gripper(self.ros_spec.gripper_command, value, ends.open, ends.closed)

    def command_gripper(self, value: float) -> None:
        gripper = self.ros_spec.gripper_command
        if gripper is None:
            raise BackendError(f"robot {self.spec.robot.name!r} declares no ros.gripper_command")
        self._check_inputs()
        self._guarded(lambda: self._publish(gripper.topic, self._gripper_message(value)))

    def stop(self) -> None:
        """Hold the arm where it is, once per event. Allowed with the gate closed: stopping is not motion."""
        with self._lock:
            if self._holding:
                return
            self._holding = True
        self._deadman_armed = False
        self.follow.clear()
        msg = messages.encode_arm_stop(self.ros_spec.arm_command, self.arm_names, self._hold_position())
        if msg is None:
            log.warning("no stop to send: no trustworthy position to hold and no command sent yet")
            return
        try:
            self.link.publish(self.ros_spec.arm_command.topic, msg)
        except ConnectionLost:
            self._stop_owed = True
            log.warning("cannot send the stop (not connected); the arm halts at the end of its last motion, "
                        "and the stop goes out on reconnection")

    def _hold_position(self) -> np.ndarray | None:
        """Where a driver without a stop of its own holds: the arm's reading if it is fresh,
        else the last commanded target (where the arm is headed anyway); never a stale reading."""
        with self._lock:
            values, received = self.joints.values, self.joints.received
        if values is not None and time.monotonic() - received <= self.joints.limit:
            return values[0][self._arm_in_states]
        return self._last_target

    def _watch_deadman(self) -> None:
        while not self._closed:
            time.sleep(POLL_S * 2)
            with self._lock:
                silent = time.monotonic() - self._last_command
            if self._deadman_armed and silent > self.real.deadman_s:
                log.warning("deadman: no command for %.2f s, stopping the arm", silent)
                self.stop()

    # ------------------------------------------------------------------ protocol

    def recover(self) -> None:
        """Reconnect if the connection is gone, clear any fault, wait for fresh readings, and
        deliver a stop that found no connection."""
        self._deadman_armed = False
        self.follow.clear()
        if not self.link.connected:
            self.link.open(self.real.reconnect_tries)
        since = min(feed.clear() for feed in self._feeds)
        self._wait_for_readings(since)
        if self._stop_owed:
            self._stop_owed = False
            with self._lock:
                self._holding = False
            self.stop()

    def reset(self, q_arm, gripper, objects) -> None:
        """Drive home at reset_speed and wait there; the objects stay where the user put them."""
        self._deadman_armed = False
        home = np.asarray(q_arm, float)
        (position, _), _ = self._fresh(self.joints)
        plan = self._drive_plan(position[self._arm_in_states], home)
        timeout = max(self.real.reset_timeout_s, plan[-1][0] + plan[-1][2] + 2.0)
        started = time.monotonic()
        sent = 0
        while True:
            (position, _), _ = self._fresh(self.joints)
            here = position[self._arm_in_states]
            while sent < len(plan) and time.monotonic() - started >= plan[sent][0]:
                _, target, segment_s = plan[sent]
                self._command_arm(here, target, segment_s)
                sent += 1
                if sent == 1 and gripper is not None and self.ros_spec.gripper_command is not None:
                    gripper_topic = self.ros_spec.gripper_command.topic
                    self._guarded(lambda: self._publish(gripper_topic, self._gripper_message(gripper)))
            self._check_follow()
            if sent == len(plan) and np.max(np.abs(here - home)) < self.real.reset_tolerance:
                break
            if time.monotonic() - started > timeout:
                self.stop()
                raise BackendError(f"the arm did not reach home within {duration(timeout)} of the reset command")
            time.sleep(POLL_S)
        for feed in self.objects.values():
            self._fresh(feed)
        self._deadman_armed = False

    def _drive_plan(self, start: np.ndarray, home: np.ndarray) -> list[tuple[float, np.ndarray, float]]:
        """(send at s, target, duration s) for each command of the drive home at reset_speed."""
        total = max(1.0, float(np.max(np.abs(home - start))) / self.real.reset_speed)
        if messages.carries_duration(self.ros_spec.arm_command):
            return [(0.0, home, total)]  # the trajectory itself carries the duration
        count = max(1, math.ceil(total / RESET_SEGMENT_S))
        step = total / count
        return [(i * step, start + (home - start) * (i + 1) / count, step) for i in range(count)]

    def apply_physics(self, change) -> None:
        raise BackendError(f"a real arm's physics cannot be set ({change.quantity}): randomization is for Sim IDs")

    def advance(self, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self._check_follow()
            time.sleep(min(POLL_S, max(0.0, deadline - time.monotonic())))

    def read_joints(self) -> JointReading:
        (position, velocity), stamp = self._fresh(self.joints)
        self._reading_age, self._reading_repeated = time.monotonic() - stamp, stamp == self._last_stamp
        self._last_stamp = stamp
        return JointReading(position.copy(), velocity.copy(), stamp)

    def step_timing(self) -> dict[str, float]:
        """How the last joint reading and the arm commands were timed: the reading's age when read, whether it
        was the one read before (a reading that did not come in time), and the command latencies measured since
        the last call (NaN: none this step). `envfactory sensing-spec` turns a log of these into sensing terms."""
        latencies = self.follow.take_latencies()
        return {"joint_reading_age_s": float(self._reading_age), "joint_reading_repeated": float(self._reading_repeated),
                "command_latency_s": float(np.mean(latencies)) if latencies else math.nan}

    def read_object(self, name: str) -> ObjectReading:
        (position, quaternion), stamp = self._fresh(self.objects[name])
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
            self.link.close()
