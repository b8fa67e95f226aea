"""The digital twin: a PyBullet robot and cube behind a rosbridge-protocol server.

It publishes the robot's joint states and the cube pose on the real topic
names with the real message types, and executes the arm and gripper commands
it receives, so a Real ID runs against it unchanged. Users rehearse on it
before touching hardware; the tests run the real client against it over a
loopback socket.
"""

from __future__ import annotations

import asyncio
import threading
import time

import numpy as np

from envfactory.backends.pybullet import PyBulletBackend
from envfactory.backends.rosbridge import messages
from envfactory.factory import blueprint
from envfactory.geometry.frames import TaskFrame
from envfactory.geometry.urdf_assembly import assemble
from envfactory.registry import records
from envfactory.twin import msgtypes
from envfactory.twin.server import Faults, Node, Received, RosbridgeServer

__all__ = ["Faults", "Received", "Twin"]

JOINT_STATE_HZ = 50.0
POSE_HZ = 30.0


def _sim_id(robot: str, task: str) -> str:
    candidates = [env_id for env_id, record in sorted(records().items())
                  if record.backend == "pybullet" and not record.goal_env]
    for env_id in candidates:
        spec = blueprint(env_id).spec
        if spec.robot.name == robot and spec.task.name == task:
            return env_id
    raise ValueError(f"no Sim ID pairs robot {robot!r} with task {task!r}")


class Twin:
    """`overrides` change the twin's spec (e.g. its topics); `topic_types` make its driver
    register topics with other types (a misconfigured driver); `group_move_s` is how long the
    driver takes for every arm command that carries no duration (its time profile), by default
    the robot's `ros.arm_command.profile_time_s`."""

    def __init__(self, robot: str, task: str = "push", host: str = "127.0.0.1", port: int = 0,
                 overrides: tuple[str, ...] = (), topic_types: dict[str, str] | None = None,
                 group_move_s: float | None = None):
        compiled = blueprint(_sim_id(robot, task), ["env.timing.realtime=true", *overrides])
        spec = compiled.spec
        self.spec = spec
        self.ros = spec.robot.ros
        if self.ros is None:
            raise ValueError(f"robot {robot!r} declares no 'ros:' topic map")
        self.group_move_s = self.ros.arm_command.profile_time_s if group_move_s is None else group_move_s
        if self.group_move_s is None and "$duration" not in self.ros.arm_command.template.placeholders():
            raise ValueError(f"robot {robot!r}: its arm commands carry no $duration; declare "
                             "ros.arm_command.profile_time_s, how long its driver takes for each, or pass group_move_s")
        self.sim = PyBulletBackend(spec, assemble(spec.robot.model, compiled.asset_root, spec.robot.name),
                                   TaskFrame.of(spec.robot))
        spawn = {name: (np.asarray(obj.spawn.position, float), np.array([0.0, 0.0, 0.0, 1.0]))
                 for name, obj in spec.task.objects.items()}
        self.sim.reset(np.asarray(spec.robot.home, float), spec.gripper_at_reset, spawn)
        self.state_names = spec.robot.state_names
        self.arm_names = spec.robot.arm_state_names
        self._arm_in_states = spec.robot.arm_state_indices
        self.server = RosbridgeServer(host, port, msgtypes.with_driver_types(self.ros.message_types))
        self._add_nodes(robot, topic_types or {})
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, name="envfactory-twin", daemon=True)
        self._publishers = []

    # ------------------------------------------------------------------ lifecycle

    def start(self) -> "Twin":
        self._thread.start()
        asyncio.run_coroutine_threadsafe(self.server.start(), self._loop).result(timeout=10)
        self._publishers = [
            asyncio.run_coroutine_threadsafe(self._every(1.0 / JOINT_STATE_HZ, self._publish_joint_state), self._loop),
            asyncio.run_coroutine_threadsafe(self._every(1.0 / POSE_HZ, self._publish_poses), self._loop),
        ]
        return self

    def stop(self) -> None:
        if not self._thread.is_alive():
            return
        for publisher in self._publishers:
            publisher.cancel()
        asyncio.run_coroutine_threadsafe(self.server.close(), self._loop).result(timeout=10)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout=5)
        self.sim.close()

    def __enter__(self) -> "Twin":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    @property
    def port(self) -> int:
        return self.server.port

    @property
    def faults(self) -> Faults:
        return self.server.faults

    @property
    def received(self) -> list[Received]:
        return list(self.server.received)

    def drop_connections(self) -> None:
        asyncio.run_coroutine_threadsafe(self.server.drop_connections(), self._loop).result(timeout=5)

    def kill(self, down_for: float) -> None:
        """The rosbridge server dies now and is back after `down_for` seconds (returns at once)."""
        asyncio.run_coroutine_threadsafe(self.server.kill(down_for), self._loop)
        deadline = time.monotonic() + 5.0
        while self.server.running and time.monotonic() < deadline:
            time.sleep(0.01)

    def _add_nodes(self, robot: str, topic_types: dict[str, str]) -> None:
        ros = self.ros
        typed = lambda topic, type_name: topic_types.get(topic, type_name)  # noqa: E731
        commands = {ros.arm_command.topic: (typed(ros.arm_command.topic, ros.arm_command.type), self._on_command)}
        if ros.gripper_command is not None:
            commands[ros.gripper_command.topic] = (typed(ros.gripper_command.topic, ros.gripper_command.type),
                                                   self._on_command)
        self.server.add_node(Node(f"/{robot}_driver", publishes={
            ros.joint_states.topic: typed(ros.joint_states.topic, ros.joint_states.type)}, subscribes=commands))
        self.server.add_node(Node("/cube_tracker", publishes={
            t.topic: typed(t.topic, t.type) for t in ros.object_poses.values()}))

    # ------------------------------------------------------------------ what it publishes

    async def _every(self, period: float, publish) -> None:
        while True:
            await publish()
            await asyncio.sleep(period)

    async def _publish_joint_state(self) -> None:
        topic = self.ros.joint_states.topic
        if self.faults.is_silenced(topic):
            return
        reading = self.sim.read_joints()
        position, velocity = reading.position, reading.velocity.copy()
        if self.faults.take_malformed(topic):
            position = position.copy()
            position[-1] = float("nan")  # a driver glitch; the server sends it as null
        await self.server.publish(topic, messages.encode_joint_state(self.state_names, position, velocity,
                                                                     time.time(), self.ros.joint_states.template))

    async def _publish_poses(self) -> None:
        for name, topic_spec in self.ros.object_poses.items():
            if name not in self.sim.objects:
                continue
            if self.faults.is_silenced(topic_spec.topic):
                continue
            reading = self.sim.read_object(name)
            quaternion = reading.quaternion * (3.0 if self.faults.take_malformed(topic_spec.topic) else 1.0)
            await self.server.publish(topic_spec.topic, messages.encode_pose(self.ros.task_frame_id, reading.position,
                                                                             quaternion, time.time(),
                                                                             topic_spec.template))

    # ------------------------------------------------------------------ what it executes

    def _on_command(self, topic: str, msg: dict) -> None:
        ros = self.ros
        if self.faults.ignore_commands:
            return  # taken, never executed: a controller that is not running
        if topic == ros.arm_command.topic:
            # a trajectory carries its duration; a group command moves over the driver's profile time
            target, duration = messages.decode_arm(ros.arm_command, self.arm_names, msg, self.group_move_s)
            if target is None:  # the stop: hold where the arm is now
                target = self.sim.read_joints().position[self._arm_in_states]
                duration = 0.05
            self.sim.command_joints(target, max(duration, 0.05))
        else:
            gripper = self.spec.robot.gripper
            self.sim.command_gripper(messages.decode_gripper(ros.gripper_command, msg, gripper.open, gripper.closed))
