"""The digital twin: a PyBullet robot and cube behind a rosbridge-protocol server.

It publishes the robot's joint states and the cube pose on the real topic
names with the real message types, and executes the arm and gripper commands
it receives, so a Real ID runs against it unchanged. Users rehearse on it
before touching hardware; the tests run the real client against it over a
loopback socket.
"""

from __future__ import annotations

import asyncio
import json
import math
import threading
import time

import numpy as np

from envfactory.backends.pybullet import PyBulletBackend
from envfactory.backends.rosbridge import messages
from envfactory.factory import blueprint
from envfactory.geometry.frames import TaskFrame
from envfactory.geometry.urdf_assembly import assemble
from envfactory.registration.registry import records
from envfactory.twin import msgtypes
from envfactory.twin.drivers import DRIVERS, DeclaredDriver, UrRobotDriver
from envfactory.twin.server import Faults, Node, Received, RosbridgeServer, ServiceReply

POSE_HZ = 30.0
# Only the twin has them: a person puts a real scene's objects back, and brings a real arm clear by hand.
PLACE_SERVICE, PLACE_TYPE = "/envfactory_twin/place_object", "envfactory_twin/PlaceObject"
ARM_SERVICE, ARM_TYPE = "/envfactory_twin/place_arm", "envfactory_twin/PlaceArm"


def _sim_id(robot: str, task: str) -> str:
    candidates = [
        env_id for env_id, record in sorted(records().items()) if record.backend == "sim" and not record.goal_env
    ]
    for env_id in candidates:
        spec = blueprint(env_id).spec
        if spec.robot.name == robot and spec.task.name == task:
            return env_id
    raise ValueError(f"no Sim ID pairs robot {robot!r} with task {task!r}")


class Twin:
    """`overrides` change the twin's spec (e.g. its topics); `topic_types` make its driver register topics with
    other types (a misconfigured driver). The driver is the one the robot names (`ros.driver`), played as its
    maker publishes it (twin/drivers.py) at its stock timing: `group_move_s` replaces that stock time for
    commands that carry no duration (xs_sdk's 2 s profile), `speed_scaling` is the UR controller's (1.0: the
    slider at 100%)."""

    def __init__(
        self,
        robot: str,
        task: str = "push",
        host: str = "127.0.0.1",
        port: int = 0,
        overrides: tuple[str, ...] = (),
        topic_types: dict[str, str] | None = None,
        group_move_s: float | None = None,
        speed_scaling: float = 1.0,
    ):
        compiled = blueprint(_sim_id(robot, task), ["env.timing.realtime=true", *overrides])
        spec = compiled.spec
        self.spec = spec
        self.ros = spec.robot.ros
        if self.ros is None:
            raise ValueError(f"robot {robot!r} declares no 'ros:' topic map")
        self.sim = PyBulletBackend(
            spec, assemble(spec.robot.model, compiled.asset_root, spec.robot.name), TaskFrame.of(spec.robot)
        )
        spawn = {
            name: (np.asarray(obj.spawn.position, float), np.array([0.0, 0.0, 0.0, 1.0]))
            for name, obj in spec.task.objects.items()
        }
        self.sim.reset(np.asarray(spec.robot.home, float), spec.gripper_at_reset, spawn)
        self.state_names = spec.robot.state_names
        self.arm_names = spec.robot.arm_state_names
        self.arm_in_states = spec.robot.arm_state_indices
        self.driver = self._driver(group_move_s, speed_scaling)
        types = msgtypes.with_driver_types({**self.ros.message_types, **self.driver.message_types})
        self.server = RosbridgeServer(host, port, types)
        self._add_nodes(robot, topic_types or {})
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, name="envfactory-twin", daemon=True)
        self._publishers = []

    def _driver(self, group_move_s: float | None, speed_scaling: float):
        kind = DRIVERS.get(self.ros.driver or "", DeclaredDriver)
        if speed_scaling != 1.0 and kind is not UrRobotDriver:
            raise ValueError(
                f"speed scaling is the UR trajectory controller's; {self.spec.robot.name} runs "
                f"{self.ros.driver or 'a driver the twin plays from its topic map'}"
            )
        if kind is UrRobotDriver:
            return kind(self, group_move_s, speed_scaling)
        return kind(self, group_move_s)

    @property
    def group_move_s(self) -> float:
        """How long the driver now takes for a command that carries no duration."""
        return self.driver.group_move_s

    # ------------------------------------------------------------------ lifecycle

    def start(self) -> "Twin":
        self._thread.start()
        asyncio.run_coroutine_threadsafe(self.server.start(), self._loop).result(timeout=10)
        self._publishers = [
            asyncio.run_coroutine_threadsafe(
                self._every(1.0 / self.driver.joint_state_hz, self._publish_joint_state), self._loop
            ),
            asyncio.run_coroutine_threadsafe(self._every(1.0 / POSE_HZ, self._publish_poses), self._loop),
            asyncio.run_coroutine_threadsafe(
                self._every(1.0 / self.driver.extras_hz, lambda: self.driver.publish_extras(self.server)), self._loop
            ),
        ]
        return self

    def stop(self) -> None:
        if not self._thread.is_alive():
            return
        self.driver.close()
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

    def publish_soon(self, topic: str, msg: dict) -> None:
        """Publish from another thread (a driver's worker)."""
        if self._loop.is_running():
            asyncio.run_coroutine_threadsafe(self.server.publish(topic, msg), self._loop)

    def _add_nodes(self, robot: str, topic_types: dict[str, str]) -> None:
        ros = self.ros
        typed = lambda topic, type_name: topic_types.get(topic, type_name)  # noqa: E731
        commands = {ros.arm_command.topic: (typed(ros.arm_command.topic, ros.arm_command.type), self._on_command)}
        if ros.gripper_command is not None:
            commands[ros.gripper_command.topic] = (
                typed(ros.gripper_command.topic, ros.gripper_command.type),
                self._on_command,
            )
        publishes = {
            ros.joint_states.topic: typed(ros.joint_states.topic, ros.joint_states.type),
            **{topic: typed(topic, type_name) for topic, type_name in self.driver.publishes().items()},
        }
        self.server.add_node(
            Node(f"/{robot}_driver", publishes=publishes, subscribes=commands, services=self.driver.services()),
            self.driver.service_types,
        )
        self.server.add_node(
            Node("/cube_tracker", publishes={t.topic: typed(t.topic, t.type) for t in ros.object_poses.values()})
        )
        self.server.add_node(
            Node(
                "/envfactory_twin",
                services={PLACE_SERVICE: (PLACE_TYPE, self._place_object), ARM_SERVICE: (ARM_TYPE, self._place_arm)},
            ),
            {
                PLACE_TYPE: ({"name": "string", "position": "float64[]"}, {}),
                ARM_TYPE: ({"position": "float64[]", "gripper": "float64"}, {}),
            },
        )

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
        names, position, velocity = self.driver.joint_state(reading.position, reading.velocity.copy())
        if self.faults.take_malformed(topic):
            position = position.copy()
            position[-1] = float("nan")  # a driver glitch; the server sends it as null
        await self.server.publish(
            topic, messages.encode_joint_state(names, position, velocity, time.time(), self.ros.joint_states.template)
        )

    async def _publish_poses(self) -> None:
        for name, topic_spec in self.ros.object_poses.items():
            if name not in self.sim.objects:
                continue
            if self.faults.is_silenced(topic_spec.topic):
                continue
            reading = self.sim.read_object(name)
            quaternion = reading.quaternion * (3.0 if self.faults.take_malformed(topic_spec.topic) else 1.0)
            await self.server.publish(
                topic_spec.topic,
                messages.encode_pose(
                    self.ros.task_frame_id, reading.position, quaternion, time.time(), topic_spec.template
                ),
            )

    # ------------------------------------------------------------------ what it executes

    def _place_object(self, request: dict) -> ServiceReply:
        """The person who puts the cube back between episodes, as a service only the twin has (for rehearsals
        and benchmarks that start each episode where a simulated one starts): a task object, at rest at a
        task-frame position, the arm left as it is."""
        name, position = request.get("name", ""), list(request.get("position") or [])
        if name not in self.spec.task.objects:
            return ServiceReply(False, f"no object {name!r} in the task (it has {sorted(self.spec.task.objects)})")
        if len(position) != 3 or not all(math.isfinite(value) for value in position):
            return ServiceReply(False, f"position {position} is not a task-frame point x, y, z")
        self.sim.place_objects({name: (np.asarray(position, float), np.array([0.0, 0.0, 0.0, 1.0]))})
        return ServiceReply(True, {})

    def _place_arm(self, request: dict) -> ServiceReply:
        """The person who brings the arm clear by hand (freedrive) when the env refuses to drive it home: the arm
        at rest at joint positions (action order) within its limits, the gripper at a value in its range; its
        driver then holds it there."""
        position, robot = list(request.get("position") or []), self.spec.robot
        joints = robot.arm_joints
        if len(position) != len(joints) or not all(math.isfinite(value) for value in position):
            return ServiceReply(False, f"position {position} is not one value for each of the {len(joints)} arm joints")
        outside = [j.name for j, value in zip(joints, position) if not j.lower <= value <= j.upper]
        if outside:
            return ServiceReply(False, f"position {position} lies outside the limits of {outside}")
        gripper = request.get("gripper")
        if robot.gripper is not None:
            bounds = sorted((robot.gripper.open, robot.gripper.closed))
            if not (isinstance(gripper, (int, float)) and bounds[0] <= gripper <= bounds[1]):
                return ServiceReply(False, f"gripper {gripper} lies outside its range {bounds}")
        q_arm = np.asarray(position, float)
        self.sim.place_arm(q_arm, None if robot.gripper is None else float(gripper))
        self.driver.move_arm(q_arm, 0.0)  # a new goal where the arm now is: no earlier goal pulls it back
        return ServiceReply(True, {})

    def _on_command(self, topic: str, msg: dict) -> None:
        if self.faults.ignore_commands:
            return  # taken, never executed: a controller that is not running
        if topic == self.ros.arm_command.topic:
            self.driver.on_arm(msg)
        else:
            self.driver.on_gripper(msg)


def place_object(port: int, name: str, position, host: str = "127.0.0.1") -> None:
    """Ask a running twin (in any process) to put a task object at rest at `position` (task frame), as a person
    puts the cube back between real episodes."""
    args = {"name": name, "position": [float(value) for value in position]}
    _call_twin(port, host, PLACE_SERVICE, args, f"place {name} at {args['position']}")


def place_arm(port: int, q_arm, gripper: float | None, host: str = "127.0.0.1") -> None:
    """Ask a running twin (in any process) to put its arm at rest at `q_arm` (action order) and the gripper at
    `gripper`, as a person brings a real arm clear by hand."""
    args = {"position": [float(value) for value in q_arm], "gripper": None if gripper is None else float(gripper)}
    _call_twin(port, host, ARM_SERVICE, args, f"place the arm at {args['position']}")


def _call_twin(port: int, host: str, service: str, args: dict, what: str) -> None:
    from websockets.sync.client import connect

    with connect(f"ws://{host}:{port}") as websocket:
        websocket.send(json.dumps({"op": "call_service", "service": service, "args": args, "id": service}))
        while True:
            reply = json.loads(websocket.recv(timeout=5.0))
            if reply.get("op") == "service_response":
                break
    if not reply.get("result"):
        raise RuntimeError(f"the twin at port {port} did not {what}: {reply.get('values')}")
