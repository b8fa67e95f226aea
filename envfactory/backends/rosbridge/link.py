"""One rosbridge connection at a time, opened (and reopened) by us within bounds.

roslibpy's own reconnect is switched off: it gives up after a few tries and,
while it waits, queues publishes that would reach the arm late. Instead every
(re)connection is a fresh client, tried with backoff a bounded number of times,
so nothing queued on a dead connection is ever replayed. Before anything is
advertised, each command topic is checked with rosapi (where the server runs it,
as the standard rosbridge launch does): something must subscribe to it, with the
type we send.
"""

from __future__ import annotations

import logging
import time
from typing import Callable

from envfactory.backends.base import CommandRefused, ConnectionLost, DriverRefused
from envfactory.schema.models import RealSettings, RosSpec, RosTopic

log = logging.getLogger("envfactory.rosbridge")


class _QuietGivingUp(logging.Filter):
    """roslibpy warns each time a connection it may not retry ends; the retrying is ours."""

    def filter(self, record: logging.LogRecord) -> bool:
        return "max reconnect retries" not in record.getMessage()


logging.getLogger("roslibpy").addFilter(_QuietGivingUp())

# backoff between connection tries: INITIAL, then FACTOR times longer, at most MAX
RECONNECT_INITIAL_S, RECONNECT_FACTOR, RECONNECT_MAX_S = 0.25, 2.0, 2.0
ROSAPI_TIMEOUT_S = 2.0
POLL_S = 0.01


def backoff(tries: int) -> list[float]:
    """The waits before each try after the first."""
    return [min(RECONNECT_INITIAL_S * RECONNECT_FACTOR**i, RECONNECT_MAX_S) for i in range(max(tries - 1, 0))]


class Link:
    """One rosbridge connection, opened and reopened within bounds by this side (never by roslibpy), with the
    command topics checked through rosapi at every connection, every subscription wired again, and a driver's
    services called."""

    def __init__(self, real: RealSettings, ros_spec: RosSpec, subscriptions: dict[str, tuple[str, Callable]]):
        """`subscriptions`: topic -> (type, callback(msg))."""
        self.real, self.ros_spec = real, ros_spec
        self.subscriptions = subscriptions
        self.ros = None
        self._topics: dict[str, object] = {}

    @property
    def url(self) -> str:
        return f"ws://{self.real.host}:{self.real.port}"

    @property
    def connected(self) -> bool:
        return self.ros is not None and self.ros.is_connected

    # ------------------------------------------------------------------ opening

    def open(self, tries: int) -> None:
        """Connect within `tries` tries, check the command topics, wire every topic.
        ConnectionLost when the server cannot be reached; CommandRefused when a command
        topic has no subscriber of our type."""
        self.close()
        waits = backoff(tries)
        started = time.monotonic()
        for attempt in range(tries):
            if self._try_connect():
                break
            if attempt == tries - 1:
                raise ConnectionLost(
                    f"cannot reach rosbridge at {self.url}: {tries} connection tries over "
                    f"{time.monotonic() - started:.2f} s failed (is rosbridge_server running?). The arm stops at "
                    f"the end of its last segment."
                )
            time.sleep(waits[attempt])
        try:
            self._check_command_topics()
            self._wire()
        except BaseException:
            self.close()
            raise

    def _try_connect(self) -> bool:
        import roslibpy

        ros = roslibpy.Ros(self.real.host, self.real.port, transport="asyncio")
        ros.factory.maxRetries = 0  # reconnection is ours (see the module docstring)
        deadline = time.monotonic() + self.real.connect_timeout_s
        while time.monotonic() < deadline:
            if ros.is_connected:
                self.ros = ros
                return True
            if getattr(ros.factory, "_retry_count", 0) > 0:  # the try failed and roslibpy stood down
                return False
            time.sleep(POLL_S)
        _close_quietly(ros)
        return False

    def _wire(self) -> None:
        import roslibpy

        for topic, (type_name, callback) in self.subscriptions.items():
            subscriber = roslibpy.Topic(self.ros, topic, type_name, reconnect_on_close=False)
            subscriber.subscribe(callback)
        for command in self._commands():
            publisher = roslibpy.Topic(self.ros, command.topic, command.type, reconnect_on_close=False)
            publisher.advertise()
            self._topics[command.topic] = publisher

    def _commands(self) -> list[RosTopic]:
        return [c for c in (self.ros_spec.arm_command, self.ros_spec.gripper_command) if c is not None]

    # ------------------------------------------------------------------ rosapi

    def _check_command_topics(self) -> None:
        for command in self._commands():
            try:
                type_name = self._rosapi("/rosapi/topic_type", "rosapi/TopicType", {"topic": command.topic})["type"]
                subscribers = self._rosapi("/rosapi/subscribers", "rosapi/Subscribers", {"topic": command.topic})[
                    "subscribers"
                ]
            except _NoRosapi as exc:
                log.warning(
                    "cannot check %s before sending to it (%s); the follow watchdog still catches "
                    "commands nothing executes",
                    command.topic,
                    exc,
                )
                return
            if type_name and not same_type(type_name, command.type):
                raise CommandRefused(
                    f"{command.topic} has type {type_name} on the robot, but this env sends {command.type} there: "
                    f"the server would refuse every command. Fix the topic map (robots/*.yaml 'ros:', or the "
                    f"*_command_topic kwargs) or the driver."
                )
            if not subscribers:
                raise CommandRefused(
                    f"nothing subscribes to {command.topic} ({command.type}): no driver would execute the commands. "
                    f"Is the driver running, and is the topic right?"
                )

    def _rosapi(self, service: str, type_name: str, request: dict) -> dict:
        import roslibpy

        try:
            reply = roslibpy.Service(self.ros, service, type_name).call(
                roslibpy.ServiceRequest(request), timeout=min(ROSAPI_TIMEOUT_S, self.real.connect_timeout_s)
            )
        except Exception as exc:  # no rosapi node, or it did not answer: the check is skipped, not failed
            raise _NoRosapi(f"{service}: {exc}") from None
        return dict(reply)

    # ------------------------------------------------------------------ use

    def call(self, service: str, type_name: str, request: dict) -> dict:
        """A driver's service, answered within connect_timeout_s; DriverRefused says why not."""
        import roslibpy

        if not self.connected:
            raise ConnectionLost(f"lost the rosbridge connection to {self.url}: {service} not called")
        try:
            reply = roslibpy.Service(self.ros, service, type_name).call(
                roslibpy.ServiceRequest(request), timeout=self.real.connect_timeout_s
            )
        except Exception as exc:  # roslibpy raises its own for a failed call and a bare one for a timeout
            raise DriverRefused(f"{service} ({type_name}) refused {request}: {exc or type(exc).__name__}") from None
        return dict(reply)

    def publish(self, topic: str, msg: dict) -> None:
        import roslibpy

        if not self.connected:
            raise ConnectionLost(f"lost the rosbridge connection to {self.url}: command on {topic} not sent")
        self._topics[topic].publish(roslibpy.Message(msg))

    def close(self) -> None:
        if self.ros is not None:
            _close_quietly(self.ros)
        self.ros, self._topics = None, {}


class _NoRosapi(Exception):
    pass


def same_type(a: str, b: str) -> bool:
    # ROS 2 spells trajectory_msgs/JointTrajectory as trajectory_msgs/msg/JointTrajectory
    return a.replace("/msg/", "/") == b.replace("/msg/", "/")


def _close_quietly(ros) -> None:
    try:
        ros.close(timeout=1.0)
    except Exception:  # closing a dead connection: nothing left to tell it
        pass
