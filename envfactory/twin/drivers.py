"""The drivers the twin plays, each as its maker publishes it: what it publishes on /joint_states, how it
carries out arm and gripper commands, its services and its actions.

The twin must not share the env's beliefs about a driver, or the tests that run the env against it could not
catch a wrong one. So a named driver here decodes its maker's messages itself and keeps its maker's message
and service definitions, its stock timing and its units; only a robot without a named driver (`ros.driver`)
is played from its own topic map, as it declares it.

Sources: xs_sdk (Interbotix interbotix_ros_core: xs_sdk_obj.cpp, OperatingModes.srv; the xsarm_control
configs' modes.yaml and per-model motor configs), ur_robot_driver (Universal Robots' ROS driver and its scaled
joint trajectory controller), ned_ros (Niryo's tools commander, tools_definition.yaml and the Gazebo SRDF).
"""

from __future__ import annotations

import math
import threading
import time

import numpy as np

from envfactory.backends.rosbridge import messages
from envfactory.twin.server import ServiceReply

MIN_MOVE_S = 0.05  # the shortest motion the twin's arm plays (a 0 profile: the motors' own top speed)


class DeclaredDriver:
    """A driver known only by the robot's topic map: commands as its templates say, over their duration or the
    declared profile time."""

    joint_state_hz = 50.0
    extras_hz = 10.0  # how often publish_extras runs
    message_types: dict[str, dict[str, str]] = {}  # the maker's own definitions, over the robot's declared ones
    service_types: dict[str, tuple[dict[str, str], dict[str, str]]] = {}

    def __init__(self, twin, stock_move_s: float | None):
        self.twin, self.ros, self.sim = twin, twin.ros, twin.sim
        self.group_move_s = stock_move_s if stock_move_s is not None else self.ros.arm_command.profile_time_s
        self.gripper = twin.spec.robot.gripper
        self._hold_lock = threading.Lock()
        self._hold: threading.Timer | None = None
        self._commands = 0  # arm commands so far: a hold is for the command it was set for only
        self._stopped = False  # closed: the twin is shutting down its simulation

    # what it publishes
    def joint_state(self, position: np.ndarray, velocity: np.ndarray) -> tuple[list[str], np.ndarray, np.ndarray]:
        return self.twin.state_names, position, velocity

    def publishes(self) -> dict[str, str]:
        """Topics the driver publishes beyond its joint states (topic -> type)."""
        return {}

    async def publish_extras(self, server) -> None:
        """Messages it publishes at the joint-state rate beyond the joint states."""

    def services(self) -> dict:
        """service -> (type, handler(request) -> ServiceReply)."""
        return {}

    # what it executes
    def on_arm(self, msg: dict) -> None:
        target, duration = messages.decode_arm(self.ros.arm_command, self.twin.arm_names, msg, self.group_move_s)
        self.move_arm(target, duration)

    def move_arm(self, target, duration: float) -> None:
        with self._hold_lock:
            if self._stopped:
                return
            if target is None:  # the stop: hold where the arm is now
                target = self.sim.read_joints().position[self.twin.arm_in_states]
                duration = MIN_MOVE_S
            duration = max(duration, MIN_MOVE_S)
            self._commands += 1
            if self._hold is not None:
                self._hold.cancel()
            self.sim.command_joints(target, duration)
            # Once its profile is over, a servo's position loop holds the goal with all the torque and speed it
            # has (a Dynamixel's profile has ended at the goal; UR's trajectory controller holds its last point).
            # A joint pushed back by what it presses on then returns at its own top speed, not at the pace of
            # the profile it was given.
            self._hold = threading.Timer(duration, self._hold_goal, (target, self._commands))
            self._hold.daemon = True
            self._hold.start()

    def _hold_goal(self, target, command: int) -> None:
        with self._hold_lock:
            if command == self._commands and not self._stopped:
                self.sim.hold_joints(target)

    def on_gripper(self, msg: dict) -> None:
        self.sim.command_gripper(
            messages.decode_gripper(self.ros.gripper_command, msg, self.gripper.open, self.gripper.closed)
        )

    def close(self) -> None:
        with self._hold_lock:
            self._stopped = True
            if self._hold is not None:
                self._hold.cancel()


# ---------------------------------------------------------------------------------------------------- xs_sdk

# xs_sdk's own gripper linkage (horn_radius, arm_length, m), when the motor config gives none
XS_DEFAULT_LINKAGE = {"horn_radius": 0.014, "arm_length": 0.024}
XS_GROUPS = ("arm", "all")
XS_MODES = ("position", "ext_position", "velocity", "current", "current_based_position", "pwm", "linear_position")


class XsSdk(DeclaredDriver):
    """Interbotix xs_sdk. The arm group runs its stock time profile (modes.yaml: 2000 ms, 300 ms to accelerate)
    until set_operating_modes changes it; the gripper runs in pwm, where a JointSingleCommand's cmd is a PWM
    (cast to an integer: 0.05 is 0, and nothing moves). In linear_position mode cmd is the distance between the
    two fingers, turned into a horn angle through the linkage; a distance the linkage cannot reach gives NaN,
    which the motor takes as its zero angle. /joint_states carries the horn angle as `gripper` and each
    finger's half of the distance."""

    joint_state_hz = 100.0  # joint_state_publisher.update_rate in the xsarm configs
    STOCK_PROFILE_S = 2.0
    service_types = {
        "interbotix_xs_msgs/OperatingModes": (
            {
                "cmd_type": "string",
                "name": "string",
                "mode": "string",
                "profile_type": "string",
                "profile_velocity": "int32",
                "profile_acceleration": "int32",
            },
            {},
        )
    }
    message_types = {
        "interbotix_xs_msgs/JointGroupCommand": {"name": "string", "cmd": "float32[]"},
        "interbotix_xs_msgs/JointSingleCommand": {"name": "string", "cmd": "float32"},
    }

    def __init__(self, twin, stock_move_s: float | None):
        super().__init__(twin, self.STOCK_PROFILE_S if stock_move_s is None else stock_move_s)
        self.arm_speed: float | None = None  # rad/s under a velocity profile; None under a time profile
        config = {**XS_DEFAULT_LINKAGE, **self.ros.driver_config}  # the robot's motor config, as xs_sdk reads it
        self.horn, self.arm_length = float(config["horn_radius"]), float(config["arm_length"])
        self.gripper_mode = "pwm"
        self.namespace = "/" + twin.spec.robot.name

    def services(self) -> dict:
        return {f"{self.namespace}/set_operating_modes": ("interbotix_xs_msgs/OperatingModes", self._set_modes)}

    def _set_modes(self, request: dict) -> ServiceReply:
        cmd_type, name = request.get("cmd_type", ""), request.get("name", "")
        joints = [*self.twin.arm_names, "gripper"]
        if (
            cmd_type == "group"
            and name not in XS_GROUPS
            or cmd_type == "single"
            and name not in joints
            or cmd_type not in ("group", "single")
        ):
            return ServiceReply(
                False, f"Invalid service call. {cmd_type.capitalize() or 'Type'} '{name}' does not exist."
            )
        mode = request.get("mode", "")
        if mode not in XS_MODES:
            return ServiceReply(True, {})  # xs_sdk logs the bad mode per motor, skips it, and answers true
        if name == "gripper":
            self.gripper_mode = mode
        elif mode == "position":
            velocity = max(request.get("profile_velocity", 0), 0)  # 0: no limit, the motors' own top speed
            if request.get("profile_type") == "time":
                self.group_move_s, self.arm_speed = velocity / 1000.0, None
            else:  # Dynamixel velocity units of 0.229 rev/min
                self.group_move_s, self.arm_speed = 0.0, (velocity * 0.229 * 2 * math.pi / 60 or None)
        return ServiceReply(True, {})

    def on_arm(self, msg: dict) -> None:
        if msg.get("name") not in XS_GROUPS:
            raise ValueError(f"group {msg.get('name')!r} does not exist")
        target = np.asarray(msg["cmd"], float)
        if target.shape != (len(self.twin.arm_names),):
            raise ValueError(f"{len(target)} commands for {len(self.twin.arm_names)} joints: not executed")
        duration = self.group_move_s
        if self.arm_speed is not None:  # a velocity profile: as long as the furthest joint needs at that speed
            here = self.sim.read_joints().position[self.twin.arm_in_states]
            duration = float(np.max(np.abs(target - here))) / self.arm_speed
        self.move_arm(target, duration)

    def on_gripper(self, msg: dict) -> None:
        if msg.get("name") != "gripper":
            raise ValueError(f"joint {msg.get('name')!r} does not exist")
        command = float(msg["cmd"])
        if self.gripper_mode == "pwm":
            pwm = int(command)  # written to Goal_PWM as an integer
            if pwm:
                self.sim.command_gripper(self.gripper.open if pwm > 0 else self.gripper.closed)
            return
        if self.gripper_mode != "linear_position":
            raise ValueError(f"the gripper runs in {self.gripper_mode} mode: this twin plays pwm and linear_position")
        self.sim.command_gripper(self.finger(self.horn_angle(command)))

    def horn_angle(self, distance: float) -> float:
        """The motor angle for a distance between the fingers; the motor's zero angle where the linkage cannot
        reach (the conversion's NaN)."""
        half = distance / 2.0
        with np.errstate(all="ignore"):
            cosine = (self.horn**2 + half**2 - self.arm_length**2) / (2 * self.horn * half) if half else math.nan
        return 0.0 if not -1.0 <= cosine <= 1.0 else math.pi / 2 - math.acos(cosine)

    def finger(self, angle: float) -> float:
        """One finger's position from the centre for a horn angle, as xs_sdk publishes it."""
        return self.horn * math.sin(angle) + math.sqrt(self.arm_length**2 - (self.horn * math.cos(angle)) ** 2)

    def joint_state(self, position, velocity):
        """The horn's angle and speed (the motor's own readings) as `gripper`; each finger's position from it, and
        a finger velocity of 0, as xs_sdk publishes them."""
        names = self.twin.state_names
        position, velocity = position.copy(), velocity.copy()
        if "gripper" in names and self.gripper is not None:
            finger, step = position[names.index(self.gripper.joint)], 1e-5
            position[names.index("gripper")] = self.horn_angle(2 * finger)
            slope = (self.horn_angle(2 * (finger + step)) - self.horn_angle(2 * (finger - step))) / (2 * step)
            velocity[names.index("gripper")] = slope * velocity[names.index(self.gripper.joint)]
            for side in ("left_finger", "right_finger"):
                if side in names:
                    velocity[names.index(side)] = 0.0
        return names, position, velocity


# ---------------------------------------------------------------------------------------------------- UR


class UrRobotDriver(DeclaredDriver):
    """ur_robot_driver's scaled joint trajectory controller: a trajectory's time runs at the speed scaling
    (the teach pendant's slider times the controller's own slow-down), which it publishes on
    /speed_scaling_factor. Stock: 1.0 (the slider at 100%)."""

    joint_state_hz = 125.0  # the e-Series streams at 500 Hz; the twin publishes a quarter of that
    extras_hz = 125.0

    def __init__(self, twin, stock_move_s: float | None, speed_scaling: float = 1.0):
        super().__init__(twin, stock_move_s)
        self.speed_scaling = speed_scaling

    def publishes(self) -> dict[str, str]:
        return {"/speed_scaling_factor": "std_msgs/Float64"}

    async def publish_extras(self, server) -> None:
        await server.publish("/speed_scaling_factor", {"data": float(self.speed_scaling)})

    def on_arm(self, msg: dict) -> None:
        target, duration = messages.decode_arm(self.ros.arm_command, self.twin.arm_names, msg, 0.0)
        self.move_arm(target, duration / max(self.speed_scaling, 1e-3))


# ---------------------------------------------------------------------------------------------------- Niryo

NIRYO_ACTION = "/niryo_robot_tools_commander/action_server"
NIRYO_GRIPPER_1 = 11  # Gripper 1's tool id
NIRYO_JAWS = {1: 0.007, 2: -0.01}  # OPEN_GRIPPER, CLOSE_GRIPPER: the jaw positions of Niryo's own simulation
NIRYO_STILL_POLL_S, NIRYO_STILL_READS, NIRYO_TIMEOUT_S = 0.05, 10, 3.0
GOAL_ACTIVE, GOAL_SUCCEEDED, GOAL_ABORTED = 1, 3, 4
TOOL_SUCCESS, TOOL_FAILURE = 1, -251  # niryo_robot_msgs/CommandStatus


class NedRos(DeclaredDriver):
    """Niryo's ned_ros with Gripper 1. /joint_states carries joint_1..joint_6 only (the jaws are in
    Niryo's Gazebo model alone). The tools commander runs one goal at a time, in the order they came: a goal
    for another tool aborts with its reason; open and close drive the jaws, wait until they have been still for
    ten reads 50 ms apart (at most 3 s), then succeed."""

    joint_state_hz = 50.0  # joint_state_controller's publish_rate
    extras_hz = 5.0  # actionlib's status_frequency
    message_types = {
        "niryo_robot_tools_commander/ToolCommand": {
            "cmd_type": "uint8",
            "tool_id": "int8",
            "speed": "uint16",
            "max_torque_percentage": "uint8",
            "hold_torque_percentage": "uint8",
            "activate": "bool",
            "gpio": "string",
        },
        "niryo_robot_tools_commander/ToolGoal": {"cmd": "niryo_robot_tools_commander/ToolCommand"},
        "niryo_robot_tools_commander/ToolActionGoal": {
            "header": "std_msgs/Header",
            "goal_id": "actionlib_msgs/GoalID",
            "goal": "niryo_robot_tools_commander/ToolGoal",
        },
        "niryo_robot_tools_commander/ToolResult": {"status": "int32", "message": "string"},
        "niryo_robot_tools_commander/ToolActionResult": {
            "header": "std_msgs/Header",
            "status": "actionlib_msgs/GoalStatus",
            "result": "niryo_robot_tools_commander/ToolResult",
        },
    }
    ARM_JOINTS = [f"joint_{i}" for i in range(1, 7)]

    def __init__(self, twin, stock_move_s: float | None):
        super().__init__(twin, stock_move_s)
        self.mounted_tool = NIRYO_GRIPPER_1  # the tool the robot carries (tools_definition.yaml's ids)
        self._goals: list[tuple[str, dict]] = []
        self._wake = threading.Condition()
        self._closed = False
        self.finished: list[tuple[str, int]] = []  # (goal id, status), in the order they ended
        self._worker = threading.Thread(target=self._run_goals, name="twin-tools-commander", daemon=True)
        self._worker.start()

    def joint_state(self, position, velocity):
        index = [self.twin.state_names.index(name) for name in self.ARM_JOINTS]
        return self.ARM_JOINTS, position[index], velocity[index]

    def publishes(self) -> dict[str, str]:
        return {
            f"{NIRYO_ACTION}/result": "niryo_robot_tools_commander/ToolActionResult",
            f"{NIRYO_ACTION}/status": "actionlib_msgs/GoalStatusArray",
        }

    def on_gripper(self, msg: dict) -> None:
        goal_id = msg["goal_id"]["id"]
        with self._wake:
            self._goals.append((goal_id, msg["goal"]["cmd"]))
            self._wake.notify()

    @property
    def queued(self) -> int:
        with self._wake:
            return len(self._goals)

    def _run_goals(self) -> None:
        while True:
            with self._wake:
                while not self._goals and not self._closed:
                    self._wake.wait()
                if self._closed:
                    return
                goal_id, command = self._goals[0]
            status, result = self._carry_out(command)
            self.twin.publish_soon(
                f"{NIRYO_ACTION}/result",
                messages.encode_action_result(
                    goal_id, status, "", {"status": result[0], "message": result[1]}, time.time()
                ),
            )
            with self._wake:
                self._goals.pop(0)
                self.finished.append((goal_id, status))

    def _carry_out(self, command: dict) -> tuple[int, tuple[int, str]]:
        tool = command.get("tool_id", 0)
        if tool != self.mounted_tool:
            return GOAL_ABORTED, (
                TOOL_FAILURE,
                f"Tools ID do not match -> Given : {tool} Expected : {self.mounted_tool}",
            )
        cmd_type = command.get("cmd_type")
        if cmd_type not in NIRYO_JAWS:
            return GOAL_ABORTED, (TOOL_FAILURE, f"Command '{cmd_type}' is not available for this tool")
        self.sim.command_gripper(NIRYO_JAWS[cmd_type])
        jaw = self.twin.state_names.index(self.gripper.joint)
        last, still, started = self.sim.read_joints().position[jaw], 0, time.monotonic()
        while still < NIRYO_STILL_READS and time.monotonic() - started < NIRYO_TIMEOUT_S and not self._closed:
            time.sleep(NIRYO_STILL_POLL_S)
            now = self.sim.read_joints().position[jaw]
            still = still + 1 if abs(now - last) < 1e-4 else 0
            last = now
        return GOAL_SUCCEEDED, (TOOL_SUCCESS, "Tool action successfully finished")

    async def publish_extras(self, server) -> None:
        with self._wake:
            active = [goal_id for goal_id, _ in self._goals[:1]]
        status = [
            {"goal_id": {"stamp": {"secs": 0, "nsecs": 0}, "id": goal_id}, "status": GOAL_ACTIVE, "text": ""}
            for goal_id in active
        ]
        await server.publish(
            f"{NIRYO_ACTION}/status",
            {"header": {"seq": 0, "stamp": {"secs": 0, "nsecs": 0}, "frame_id": ""}, "status_list": status},
        )

    def close(self) -> None:
        super().close()
        with self._wake:
            self._closed = True
            self._wake.notify()


DRIVERS = {"xs_sdk": XsSdk, "ur_robot_driver": UrRobotDriver, "ned_ros": NedRos}
