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

A step means what it means in simulation: the driver is given the motion's
duration (in the trajectory, or as the time profile its setup calls set at
every connection), and advance() returns once the cycle has passed and the
arm is at its target (motion.py), with a gripper goal's result in (gripper.py).
"""

from __future__ import annotations

import logging
import math
import threading
import time
from pathlib import Path

import numpy as np

from envfactory.backends.base import (
    BackendError,
    ConnectionLost,
    DriverRefused,
    JointReading,
    MalformedFeed,
    ObjectReading,
    StaleFeed,
)
from envfactory.backends.rosbridge import messages
from envfactory.backends.rosbridge.feeds import Feed, duration
from envfactory.backends.rosbridge.follow import FollowWatch
from envfactory.backends.rosbridge.gate import require_motion_gate
from envfactory.backends.rosbridge.gripper import GripperLink
from envfactory.backends.rosbridge.link import Link
from envfactory.backends.rosbridge.motion import MotionWatch, drive_plan
from envfactory.backends.rosbridge.readings import Readings
from envfactory.backends.rosbridge.templates import fill
from envfactory.backends.synchronous import synchronous_length
from envfactory.backends.view import RENDER_SIZE
from envfactory.schema.driver import RAMP_SHARE, setup_values
from envfactory.schema.models import ComposedSpec

log = logging.getLogger("envfactory.rosbridge")

POLL_S = 0.02
FIRST_CONNECT_TRIES = 3  # at construction: a robot that is not there is said so quickly


class RosbridgeBackend:
    """The Backend protocol on a real arm over rosbridge: one connection (Link), the joint-state and
    object-pose feeds with their staleness limits, the follow watchdog, a step that waits for its motion
    (MotionWatch) and the gripper's goals (GripperLink), and a deadman thread. Every fault stops the arm once
    and ends the episode with its reason; reset() recovers first."""

    teleports_on_reset = False  # the arm drives home

    def __init__(self, spec: ComposedSpec, urdf_path: Path, task_frame, render_mode: str | None = None):
        robot, real = spec.robot, spec.env.real
        self.spec, self.real = spec, real
        if robot.ros is None:
            raise BackendError(f"robot {robot.name!r} declares no 'ros:' topic map in its YAML")
        if real.auto_launch_cube_tracker:
            raise BackendError(
                "auto_launch_cube_tracker=True: envfactory does not launch trackers. Start the "
                f"{real.cube_tracker_camera} cube tracker yourself, then make the env with it False."
            )
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
        self._velocities = np.asarray(robot.arm_velocities, float)
        # How long the driver takes for an arm command that carries no duration: the motion time its setup
        # gives it (long enough for the largest joint change the safety check lets through, at the joints'
        # speed limits over the profile's cruise), else its stock profile
        self.motion_s = max(
            spec.env.timing.action_speed,
            spec.env.safety.max_joint_delta / float(self._velocities.min()) / (1.0 - RAMP_SHARE),
        )
        self._driver_motion_s = self.motion_s if ros.motion_set_by_setup else ros.arm_command.profile_time_s

        self._lock = threading.Lock()
        self.follow = FollowWatch(ros.arm_command.topic, real.follow_timeout_s)
        self.motion = MotionWatch(ros.arm_command.topic, ros.settle)
        self.gripper = (
            GripperLink(ros.gripper_command, robot.gripper, spec.gripper_assumed_at_reset)
            if ros.gripper_command is not None and robot.gripper is not None
            else None
        )
        self.readings = Readings(spec, self._lock, self.follow, self.gripper)
        self.joints, self.objects = self.readings.joints, self.readings.objects
        self._reading_age, self._reading_repeated, self._last_stamp = math.nan, False, -math.inf
        self._step_started: float | None = None  # the first command of the step under way
        self._last_step_s = math.nan
        self._last_alive = 0.0  # the last command, or the last moment a step was under way (the deadman's clock)
        self._last_target: np.ndarray | None = None
        self._deadman_armed = False
        self._holding = False  # a stop went out and no motion since: another stop adds nothing
        self._stop_owed = False  # a stop that found no connection goes out once there is one
        self._closed = False
        self.link = Link(real, ros, self.readings.subscriptions())
        self.link.open(FIRST_CONNECT_TRIES)
        try:
            self._set_up_driver()
            self._wait_for_readings(since=-math.inf)
        except BackendError:
            self.link.close()
            raise
        self._deadman = threading.Thread(target=self._watch_deadman, name="envfactory-deadman", daemon=True)
        self._deadman.start()

    def _set_up_driver(self) -> None:
        """The robot's setup calls (xs_sdk's operating modes: the arm's time profile, the gripper's mode), at every
        connection and reset: a restarted driver comes back with its stock settings. A refusal stops the env."""
        for call in self.ros_spec.setup:
            request = fill(call.request, setup_values(self.motion_s))
            try:
                self.link.call(call.service, call.type, request)
            except DriverRefused as exc:
                raise DriverRefused(
                    f"the driver refused its setup, so the arm would not move on the env's step: {exc}. Check that "
                    f"the driver is the one robots/{self.spec.robot.name}.yaml declares (ros.setup)"
                ) from None

    @property
    def url(self) -> str:
        return self.link.url

    def attach_geometry(self, collision) -> None:
        """The real arm's motions are its own: nothing to play without dynamics."""

    # ------------------------------------------------------------------ readings

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
            for feed in self.readings.feeds:
                with self._lock:
                    error = feed.error
                if error:
                    raise MalformedFeed(error)
            silent = [feed.topic for feed in self.readings.feeds if not feed.newer_than(since)]
            if not silent:
                return
            if time.monotonic() > deadline:
                break
            time.sleep(POLL_S)
        raise StaleFeed(
            f"connected to {self.url}, but nothing {'new ' if since > -math.inf else ''}arrived on "
            f"{silent} within {duration(wait)}: is the robot driver (and the cube tracker) running?"
        )

    # ------------------------------------------------------------------ commands

    def _publish(self, topic: str, msg: dict) -> None:
        require_motion_gate(self.allow_motion, "refusing to publish a command")
        self.link.publish(topic, msg)
        with self._lock:
            self._last_alive = time.monotonic()
            self._holding = False

    def _command_arm(self, q_from: np.ndarray, q_target, length_s: float) -> None:
        """Send the arm to `q_target` over `length_s` (a driver with its own time profile takes that instead)."""
        target = np.asarray(q_target, float)
        msg = messages.encode_arm(self.ros_spec.arm_command, self.arm_names, target, length_s)
        self._guarded(lambda: self._publish(self.ros_spec.arm_command.topic, msg))
        now = time.monotonic()
        self._last_target = target
        self.follow.commanded(q_from, target, now, length_s)
        self.motion.commanded(q_from, target, now, length_s)
        if self._step_started is None:
            self._step_started = now

    def _motion_length(self, q_from: np.ndarray, q_target: np.ndarray, duration_s: float) -> float:
        """How long the driver takes: the duration a simulator would play the move over, carried in the command;
        or, for a driver that takes no duration, the time profile it was given."""
        if messages.carries_duration(self.ros_spec.arm_command):
            return synchronous_length(q_from, q_target, duration_s, self._velocities)
        return self._driver_motion_s

    def command_joints(self, q_arm_target, duration: float) -> None:
        here = self._check_inputs()
        target = np.asarray(q_arm_target, float)
        self._command_arm(here, target, self._motion_length(here, target, duration))
        self._deadman_armed = True

    def _send_gripper(self, value: float) -> None:
        """The gripper command, if it differs from the last one the driver was sent."""
        msg = self.gripper.message(value, time.monotonic())
        if msg is not None:
            self._guarded(lambda: self._publish(self.gripper.topic, msg))
            if self._step_started is None:
                self._step_started = time.monotonic()

    def command_gripper(self, value: float) -> None:
        if self.gripper is None:
            raise BackendError(f"robot {self.spec.robot.name!r} declares no ros.gripper_command")
        self._check_inputs()
        self._send_gripper(value)

    def stop(self) -> None:
        """Hold the arm where it is, once per event. Allowed with the gate closed: stopping is not motion."""
        with self._lock:
            if self._holding:
                return
            self._holding = True
        self._deadman_armed = False
        self.follow.clear()
        self.motion.clear()
        msg = messages.encode_arm_stop(self.ros_spec.arm_command, self.arm_names, self._hold_position())
        if msg is None:
            log.warning("no stop to send: no trustworthy position to hold and no command sent yet")
            return
        try:
            self.link.publish(self.ros_spec.arm_command.topic, msg)
        except ConnectionLost:
            self._stop_owed = True
            log.warning(
                "cannot send the stop (not connected); the arm halts at the end of its last motion, "
                "and the stop goes out on reconnection"
            )

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
                silent = time.monotonic() - self._last_alive
            if self._deadman_armed and silent > self.real.deadman_s:
                log.warning("deadman: no command for %.2f s, stopping the arm", silent)
                self.stop()

    # ------------------------------------------------------------------ protocol

    def recover(self) -> None:
        """Reconnect if the connection is gone, clear any fault, set the driver up again, wait for fresh
        readings, and deliver a stop that found no connection."""
        self._deadman_armed = False
        self.follow.clear()
        self.motion.clear()
        self._step_started = None
        if self.gripper is not None:
            self.gripper.forget()
        if not self.link.connected:
            self.link.open(self.real.reconnect_tries)
        since = min(feed.clear() for feed in self.readings.feeds)
        self._set_up_driver()
        self._wait_for_readings(since)
        if self._stop_owed:
            self._stop_owed = False
            with self._lock:
                self._holding = False
            self.stop()

    def reset(self, q_arm, gripper, objects) -> None:
        """Drive home at reset_speed and wait there (and for the gripper's goal, if its driver answers goals);
        the objects stay where the user put them."""
        self._deadman_armed = False
        home = np.asarray(q_arm, float)
        (position, _), _ = self._fresh(self.joints)
        plan = drive_plan(
            position[self._arm_in_states],
            home,
            self.real.reset_speed,
            None if messages.carries_duration(self.ros_spec.arm_command) else self._driver_motion_s,
        )
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
                if sent == 1 and gripper is not None and self.gripper is not None:
                    self._send_gripper(gripper)
            self._check_follow()
            busy = self.gripper is not None and self._guarded(lambda: self.gripper.busy(time.monotonic()))
            if sent == len(plan) and np.max(np.abs(here - home)) < self.real.reset_tolerance and not busy:
                break
            if time.monotonic() - started > timeout:
                self.stop()
                raise BackendError(f"the arm did not reach home within {duration(timeout)} of the reset command")
            time.sleep(POLL_S)
        for feed in self.objects.values():
            self._fresh(feed)
        self.motion.clear()
        self._step_started = None
        self._deadman_armed = False

    def apply_physics(self, change) -> None:
        raise BackendError(f"a real arm's physics cannot be set ({change.quantity}): randomization is for Sim IDs")

    def advance(self, seconds: float) -> None:
        """The step's cycle: at least `seconds` from its first command, and until the commanded motion is done
        (and a gripper goal answered). A motion or goal that is overdue stops the arm and ends the episode."""
        started = time.monotonic() if self._step_started is None else self._step_started
        self._step_started = None
        while True:
            now = time.monotonic()
            with self._lock:
                self._last_alive = now  # a step under way is no silence: the deadman waits for the next one
            self._check_follow()
            (position, velocity), _ = self._fresh(self.joints)
            q_arm, qd_arm = position[self._arm_in_states], velocity[self._arm_in_states]
            self._guarded(lambda: self.motion.check(q_arm, qd_arm, now))
            busy = self.gripper is not None and self._guarded(lambda: self.gripper.busy(now))
            if now - started >= seconds and self.motion.done(q_arm, qd_arm, now) and not busy:
                break
            time.sleep(POLL_S)
        self._last_step_s = time.monotonic() - started

    def read_joints(self) -> JointReading:
        (position, velocity), stamp = self._fresh(self.joints)
        self._reading_age, self._reading_repeated = time.monotonic() - stamp, stamp == self._last_stamp
        self._last_stamp = stamp
        return JointReading(self.readings.with_gripper_commands(position), velocity.copy(), stamp)

    def step_timing(self) -> dict[str, float]:
        """How the last step was timed on the real path: the joint reading's age when read, whether it was the one
        read before (a reading that did not come in time), the command latencies measured since the last call,
        the motion's time from command to target (or to rest, held back), how far from its target it came to rest
        (rad, the largest joint's) and the step's wall time (NaN: none this step).
        `envfactory sensing-spec` turns a log of these into sensing terms."""
        latencies = self.follow.take_latencies()
        timing = {
            "joint_reading_age_s": float(self._reading_age),
            "joint_reading_repeated": float(self._reading_repeated),
            "command_latency_s": float(np.mean(latencies)) if latencies else math.nan,
            "motion_s": self.motion.motion_time(),
            "motion_gap_rad": self.motion.gap,
            "step_s": self._last_step_s,
        }
        self._last_step_s = math.nan
        return timing

    def read_object(self, name: str) -> ObjectReading:
        (position, quaternion), stamp = self._fresh(self.objects[name])
        return ObjectReading(position.copy(), quaternion.copy(), stamp)

    def mark_goal(self, position) -> None:
        pass  # nothing to draw on hardware

    def render(self, width: int = RENDER_SIZE[0], height: int = RENDER_SIZE[1]) -> np.ndarray:
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
