"""ROS message formats are templates in YAML: the shipped ones keep the bytes on the wire they
always had, a user's own robot declares new ones that the backend and the twin both speak, and a
broken template is reported with its file, line and dotted path."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from real_helpers import FAST, wait_for

from envfactory.backends.rosbridge import messages
from envfactory.factory import register_specs, unregister_folder
from envfactory.schema.models import ArmCommand, GripperCommand

ROOT = Path(__file__).parents[1]
JOINTS = ["j0", "j1", "j2"]

# The JSON the codecs wrote before the formats became templates (the hand-written encoders of
# the previous release, for these inputs): the shipped templates must reproduce it byte for byte.
BEFORE = {
    "joint_trajectory": '{"header": {"stamp": {"secs": 0, "nsecs": 0}, "frame_id": ""}, "joint_names": ["j0", "j1", '
    '"j2"], "points": [{"positions": [0.1, -0.2, 0.3], "velocities": [0.0, 0.0, 0.0], '
    '"accelerations": [], "effort": [], "time_from_start": {"secs": 1, "nsecs": 250000000}}]}',
    "joint_trajectory stop": '{"header": {"stamp": {"secs": 0, "nsecs": 0}, "frame_id": ""}, "joint_names": ["j0", '
    '"j1", "j2"], "points": []}',
    "joint_group": '{"name": "arm", "cmd": [0.1, -0.2, 0.3]}',
    "joint_group stop": '{"name": "arm", "cmd": [0.1, -0.2, 0.3]}',
    "float64_array": '{"layout": {"dim": [], "data_offset": 0}, "data": [0.7]}',
    "joint_single": '{"name": "gripper", "cmd": 0.7}',
    "joint_state": '{"header": {"stamp": {"secs": 12, "nsecs": 500000000}, "frame_id": ""}, "name": ["j0", "j1", '
    '"j2"], "position": [0.1, -0.2, 0.3], "velocity": [1.0, 2.0, 3.0], "effort": []}',
    "pose": '{"header": {"stamp": {"secs": 12, "nsecs": 500000000}, "frame_id": "world"}, "pose": {"position": '
    '{"x": 0.1, "y": -0.2, "z": 0.3}, "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}}',
}


def test_the_shipped_templates_write_the_bytes_of_before():
    q = [0.1, -0.2, 0.3]
    for encoding in ("joint_trajectory", "joint_group"):
        command = ArmCommand(topic="/a", type="t", encoding=encoding)
        assert json.dumps(messages.encode_arm(command, JOINTS, np.array(q), 1.25)) == BEFORE[encoding]
        assert json.dumps(messages.encode_arm_stop(command, JOINTS, np.array(q))) == BEFORE[f"{encoding} stop"]
    for encoding in ("float64_array", "joint_single"):
        command = GripperCommand(topic="/g", type="t", encoding=encoding)
        assert json.dumps(messages.encode_gripper(command, 0.7, 0.0, 0.8)) == BEFORE[encoding]
    assert json.dumps(messages.encode_joint_state(JOINTS, q, [1.0, 2.0, 3.0], 12.5)) == BEFORE["joint_state"]
    assert json.dumps(messages.encode_pose("world", q, [0, 0, 0, 1], 12.5)) == BEFORE["pose"]


# A robot whose arm controller takes a Float64MultiArray of positions (a ros_control
# JointGroupPositionController) and whose gripper takes a bare std_msgs/Float64.
USER_ROS = """ros:
  joint_states: {topic: /ur5e/joint_states, type: sensor_msgs/JointState}
  arm_command:
    topic: /arm_position_controller/command
    type: std_msgs/Float64MultiArray
    encoding:
      type: std_msgs/Float64MultiArray
      message: {layout: {dim: [], data_offset: 0}, data: $positions}
    profile_time_s: 0.1     # a position controller takes no duration: how long it takes for a command
  gripper_command:
    topic: /gripper_position/command
    type: std_msgs/Float64
    encoding:
      message: {data: $value}
  object_poses:
    cube: {topic: /cube_pose, type: geometry_msgs/PoseStamped}
  task_frame_id: world
"""


def _user_robot(tmp_path: Path, ros: str) -> Path:
    folder = tmp_path / "templated"
    (folder / "robots" / "assets").mkdir(parents=True)
    (folder / "specs").mkdir()
    shutil.copy(ROOT / "robots" / "assets" / "ur5e.collision.yaml", folder / "robots" / "assets")
    robot = (ROOT / "robots" / "ur5e.yaml").read_text().replace("name: ur5e", "name: templated")
    robot = robot[: robot.index("\nros:")] + "\n" + ros
    (folder / "robots" / "templated.yaml").write_text(robot)
    family = (ROOT / "specs" / "ur5e_pnp.yaml").read_text().replace("/robots@robot: ur5e", "/robots@robot: templated")
    family = re.sub(
        r"registration:.*",
        "registration:\n  ids:\n    TemplatedPnPSim-v0: {backend: sim}\n"
        "    TemplatedPnPReal-v0: {backend: rosbridge}\n",
        family,
        flags=re.S,
    )
    (folder / "specs" / "templated_pnp.yaml").write_text(family)
    return folder


def test_a_user_template_runs_end_to_end_against_the_twin(tmp_path, twin, make):
    folder = _user_robot(tmp_path, USER_ROS)
    try:
        added, problems = register_specs(folder)
        assert problems == [] and sorted(added) == ["TemplatedPnPReal-v0", "TemplatedPnPSim-v0"]
        stand_in = twin("templated", "pnp", group_move_s=0.05)
        env = make(
            "TemplatedPnPReal-v0",
            rosbridge_port=stand_in.port,
            allow_real_robot_motion=True,
            max_episode_steps=4,
            **FAST,
        )
        arm_topic = "/arm_position_controller/command"
        arm_messages = lambda: [r.msg for r in stand_in.received if r.topic == arm_topic]  # noqa: E731
        try:
            env.reset(seed=0)
            action = np.zeros(env.action_space.shape, dtype=np.float32)
            action[0] = 1.0  # turn the shoulder pan by one delta step
            action[-1] = 0.3  # and close the gripper part way
            env.step(action)
            arm = arm_messages()
            assert arm and set(arm[-1]) == {"layout", "data"} and len(arm[-1]["data"]) == 6
            sent = np.array(arm[-1]["data"])
            arm_in_states = env.unwrapped._arm_in_states
            twin_arm = lambda: stand_in.sim.read_joints().position[arm_in_states]  # noqa: E731
            # the twin read the positions through the same template and its arm went there
            assert wait_for(lambda: np.allclose(twin_arm(), sent, atol=5e-3)), (twin_arm(), sent)
            assert sent[0] == pytest.approx(env.unwrapped.home[0] + 0.05, abs=1e-3)  # one unit x delta_coeff 0.05
            gripper = [r.msg for r in stand_in.received if r.topic == "/gripper_position/command"]
            assert gripper and set(gripper[-1]) == {"data"} and isinstance(gripper[-1]["data"], float)
            knuckle = env.unwrapped._gripper_in_states
            twin_gripper = lambda: stand_in.sim.read_joints().position[knuckle]  # noqa: E731
            assert wait_for(lambda: abs(twin_gripper() - gripper[-1]["data"]) < 0.02), (twin_gripper(), gripper[-1])
            before_close = len(arm_messages())
        finally:
            env.close()
        # a template without a stop message stops by holding a known position, in the same message
        assert wait_for(lambda: len(arm_messages()) == before_close + 1)
        stop = arm_messages()[-1]
        assert set(stop) == {"layout", "data"}
        np.testing.assert_allclose(stop["data"], twin_arm(), atol=0.02)
    finally:
        unregister_folder(folder)


def test_the_twin_plays_a_command_without_a_duration_over_the_declared_profile_time(tmp_path, twin):
    folder = _user_robot(tmp_path, USER_ROS.replace("profile_time_s: 0.1", "profile_time_s: 0.3", 1))
    try:
        assert register_specs(folder)[1] == []
        assert twin("templated", "pnp").group_move_s == 0.3
    finally:
        unregister_folder(folder)


def test_commands_without_a_duration_and_without_a_profile_time_are_refused(tmp_path):
    """A real step waits for the motion its driver was given: a driver that takes no duration must say how long
    it takes, or neither the env nor the twin can know when a step's motion is done."""
    folder = _user_robot(
        tmp_path,
        USER_ROS.replace(
            "    profile_time_s: 0.1     # a position controller takes no duration: how long it takes for a command\n",
            "",
        ),
    )
    try:
        added, problems = register_specs(folder)
        assert added == [] and len(problems) == 1
        assert "templated.yaml:" in str(problems[0]) and "robot.ros.arm_command.profile_time_s" in str(problems[0])
        assert "declare that time (its stock profile), as profile_time_s" in str(problems[0])
    finally:
        unregister_folder(folder)


@pytest.mark.parametrize(
    "replace, broken, where, marker, words",
    [
        (
            "data: $positions}",
            "data: $positons}",
            "robot.ros.arm_command.encoding.message.data",
            "$positons",
            "unknown placeholder '$positons' (did you mean '$positions'?)",
        ),
        (
            "message: {data: $value}",
            "message: {data: $positions}",
            "robot.ros.gripper_command.encoding.message.data",
            "{data: $positions}",
            "placeholder $positions has no meaning in a gripper message",
        ),
        (
            "type: std_msgs/Float64MultiArray\n      message",
            "type: std_msgs/Float32MultiArray\n      message",
            "robot.ros.arm_command.type",
            "type: std_msgs/Float64MultiArray",
            "differs from the type of its message template",
        ),
    ],
)
def test_a_broken_template_names_its_file_line_and_path(tmp_path, replace, broken, where, marker, words):
    assert replace in USER_ROS
    folder = _user_robot(tmp_path, USER_ROS.replace(replace, broken, 1))
    try:
        added, problems = register_specs(folder)
        text = "\n".join(str(p) for p in problems)
        robot_file = folder / "robots" / "templated.yaml"
        lines = robot_file.read_text().splitlines()
        start = lines.index("ros:")
        line = next(i + 1 for i, text_line in enumerate(lines) if i > start and marker in text_line)
        assert f"{robot_file}:{line}: {where}: " in text, text
        assert words in text, text
        assert added == []
    finally:
        unregister_folder(folder)


def test_an_unknown_shipped_template_name_is_suggested():
    with pytest.raises(ValueError, match=r"no message template 'joint_trajectroy' .*did you mean 'joint_trajectory'"):
        ArmCommand(topic="/a", type="trajectory_msgs/JointTrajectory", encoding="joint_trajectroy")


def test_a_stop_is_told_from_a_command_and_a_malformed_command_is_named():
    command = ArmCommand(topic="/a", type="t", encoding="joint_trajectory")
    assert messages.decode_arm(command, JOINTS, messages.encode_arm_stop(command, JOINTS, None), 0.4) == (None, 0.0)
    with pytest.raises(messages.MalformedMessage, match="lacks 'points'"):
        messages.decode_arm(command, JOINTS, {"joint_names": JOINTS}, 0.4)
    group = ArmCommand(topic="/a", type="t", encoding="joint_group")
    with pytest.raises(messages.MalformedMessage, match="group command for 'gripper', expected 'arm'"):
        messages.decode_arm(group, JOINTS, {"name": "gripper", "cmd": [0, 0, 0]}, 0.4)


def test_a_broken_shipped_library_names_its_file_line_and_path(tmp_path, monkeypatch):
    from envfactory.schema import messages as templates
    from envfactory.schema.errors import SpecError

    library = tmp_path / "_messages.yaml"
    library.write_text(
        "good:\n  message: {data: $value}\nbad:\n  type: std_msgs/Float64\n  message:\n    data: $valeu\n"
    )
    monkeypatch.setattr(templates, "_library_path", lambda: library)
    templates.library.cache_clear()
    try:
        with pytest.raises(SpecError) as error:
            templates.library()
        assert f"{library}:6: bad.message.data: unknown placeholder '$valeu' (did you mean '$value'?)" in str(
            error.value
        )
        # a robot naming any shipped template then says the library is broken, and where
        with pytest.raises(ValueError, match=r"the shipped templates are broken: .*_messages.yaml:6"):
            GripperCommand(topic="/g", type="std_msgs/Float64", encoding="good")
    finally:
        templates.library.cache_clear()


# ------------------------------------------------------------ grippers that only open and close

TOOL_GOAL = "niryo_robot_tools_commander/ToolActionGoal"


def test_an_open_close_gripper_sends_the_nearer_end_with_a_fresh_goal_id():
    command = GripperCommand(topic="/g", type=TOOL_GOAL, encoding="tool_action_goal", states={"open": 1, "closed": 2})
    sent = [messages.encode_gripper(command, value, 0.01, -0.01) for value in (0.01, 0.004, -0.004, -0.01)]
    assert [m["goal"]["cmd"]["cmd_type"] for m in sent] == [1, 1, 2, 2]
    assert len({m["goal_id"]["id"] for m in sent}) == 4  # each goal is its own; a repeated id would be ignored
    assert [messages.decode_gripper(command, m, 0.01, -0.01) for m in sent] == [0.01, 0.01, -0.01, -0.01]
    foreign = json.loads(json.dumps(sent[0]))
    foreign["goal"]["cmd"]["cmd_type"] = 3  # CONTROL_GRIPPER: not a state this gripper declares
    with pytest.raises(messages.MalformedMessage, match=r"state 3 is neither open \(1\) nor closed \(2\)"):
        messages.decode_gripper(command, foreign, 0.01, -0.01)


@pytest.mark.parametrize(
    "fields, words",
    [
        ({"encoding": "tool_action_goal"}, "the template holds $state: declare states"),
        (
            {
                "encoding": "joint_single",
                "type": "interbotix_xs_msgs/JointSingleCommand",
                "states": {"open": 1, "closed": 2},
            },
            "states are declared but the template has no $state placeholder",
        ),
        (
            {"encoding": {"message": {"data": "$value", "mode": "$state"}}, "states": {"open": 1, "closed": 2}},
            "needs exactly one of the placeholders $state or $value",
        ),
    ],
)
def test_an_open_close_gripper_is_declared_whole(fields, words):
    with pytest.raises(ValueError, match=re.escape(words)):
        GripperCommand(**{"topic": "/g", "type": TOOL_GOAL, **fields})


def test_a_driver_type_with_an_unknown_field_type_is_named():
    from envfactory.twin import msgtypes

    types = msgtypes.with_driver_types({"pkg/Goal": {"cmd": "pkg/Command"}, "pkg/Command": {"kind": "uint8"}})
    msgtypes.check("pkg/Goal", {"cmd": {"kind": 2}}, types=types)
    with pytest.raises(msgtypes.FieldError, match="must be an integer"):
        msgtypes.check("pkg/Goal", {"cmd": {"kind": "close"}}, types=types)
    with pytest.raises(msgtypes.FieldError, match=r"pkg/Goal.cmd: unknown field type 'pkg/Comand'"):
        msgtypes.with_driver_types({"pkg/Goal": {"cmd": "pkg/Comand"}})
