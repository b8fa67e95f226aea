"""Each Real ID against its driver as the maker publishes it (the twin's drivers: xs_sdk, ur_robot_driver,
ned_ros), at the driver's stock timing: the step means what a simulated step means, the driver is brought to
the env's cycle through its own interface, and a driver that refuses is caught before any motion.

The twin's drivers are written from the makers' sources, not from the robot YAMLs: a YAML that misreads its
driver (a unit, a mode, a message field) fails here."""

import json
import time

import gymnasium as gym
import numpy as np
import pytest
from real_helpers import make_real, on, settled, wait_for
from websockets.sync.client import connect

from envfactory.backends.base import DriverRefused
from envfactory.experts import make_policy

VX300S_GRIPPER = "/vx300s/commands/joint_single"
NED2_GOALS = "/niryo_robot_tools_commander/action_server/goal"


def finger(stand_in):
    """The twin's left finger (or first jaw), m."""
    robot = stand_in.spec.robot
    return stand_in.sim.read_joints().position[robot.gripper_state_index]


def published(stand_in, topic, timeout=2.0):
    """One message the twin's driver publishes on `topic`, as a bare rosbridge client receives it."""
    with connect(f"ws://127.0.0.1:{stand_in.port}") as websocket:
        websocket.send(json.dumps({"op": "subscribe", "topic": topic}))
        while True:
            message = json.loads(websocket.recv(timeout=timeout))
            if message.get("op") == "publish" and message["topic"] == topic:
                return message["msg"]


# ------------------------------------------------------------------ Interbotix xs_sdk


def test_the_env_sets_xs_sdk_to_its_cycle_through_the_operating_modes_service(twin, make):
    stand_in = twin("vx300s", "reach")
    assert stand_in.group_move_s == 2.0 and stand_in.driver.gripper_mode == "pwm"  # xs_sdk's stock mode config
    env = make_real(make, "VX300SReacherReal-v0", stand_in)
    calls = [
        (request["cmd_type"], request["name"], request["mode"], answered)
        for _, request, answered in stand_in.server.calls
    ]
    assert calls == [("group", "arm", "position", True), ("single", "gripper", "linear_position", True)]
    motion = env.unwrapped.backend.motion_s
    assert stand_in.group_move_s == pytest.approx(round(1000 * motion) / 1000)
    assert stand_in.server.calls[0][1]["profile_type"] == "time"


@pytest.mark.parametrize(
    "robot, env_id, open_, closed",
    [("vx300s", "VX300SPnPReal-v0", 0.057, 0.021), ("rx200", "RX200PnPReal-v0", 0.037, 0.015)],
)
def test_the_interbotix_gripper_opens_to_its_full_width_and_closes_within_its_range(
    twin, make, robot, env_id, open_, closed
):
    stand_in = twin(robot, "pnp")
    env = make_real(make, env_id, stand_in, max_episode_steps=6)
    env.reset(seed=0)
    for value in (open_, closed, open_):
        action = np.zeros(env.action_space.shape, dtype=np.float32)
        action[-1] = value
        env.step(action)
        assert wait_for(lambda: abs(finger(stand_in) - value) < 1e-3), (value, finger(stand_in))
    assert all(np.isfinite(m["cmd"]) for m in on(stand_in, f"/{robot}/commands/joint_single"))
    # xs_sdk publishes the horn angle as `gripper` beside the fingers: it is finite and fits the fingers
    state = published(stand_in, f"/{robot}/joint_states")
    names = state["name"]
    assert {"gripper", "left_finger", "right_finger"} <= set(names)
    horn = state["position"][names.index("gripper")]
    assert state["position"][names.index("left_finger")] == pytest.approx(stand_in.driver.finger(horn), abs=1e-6)


def test_in_xs_sdk_stock_pwm_mode_a_finger_position_moves_nothing(twin, make):
    """What went wrong before the setup call: xs_sdk's stock config runs the gripper in pwm, where a finger
    position of 0.057 m is a PWM of 0."""
    stand_in = twin("vx300s", "pnp")
    env = make_real(make, "VX300SPnPReal-v0", stand_in, overrides=["robot.ros.setup=[]"], max_episode_steps=4)
    env.reset(seed=0)
    before = finger(stand_in)
    action = np.zeros(7, dtype=np.float32)
    action[-1] = 0.021 if before > 0.04 else 0.057
    env.step(action)
    time.sleep(0.5)
    assert finger(stand_in) == pytest.approx(before, abs=1e-4)


def test_a_driver_that_refuses_its_setup_stops_the_env_before_any_motion(twin, make):
    stand_in = twin("vx300s", "reach")
    stand_in.faults.refuse_services.add("/vx300s/set_operating_modes")
    with pytest.raises(DriverRefused) as refused:
        make_real(make, "VX300SReacherReal-v0", stand_in)
    assert "the driver refused its setup" in str(refused.value)
    assert "/vx300s/set_operating_modes" in str(refused.value) and "robots/vx300s.yaml" in str(refused.value)
    assert stand_in.received == [] and stand_in.group_move_s == 2.0


def test_an_unknown_group_is_refused_as_xs_sdk_refuses_it(twin, make):
    stand_in = twin("vx300s", "reach")
    with pytest.raises(DriverRefused, match="responded with an error"):
        make_real(make, "VX300SReacherReal-v0", stand_in, overrides=["robot.ros.setup.0.request.name=arms"])
    assert any("Group 'arms' does not exist" in error for error in stand_in.server.errors)


def test_the_watchdog_judges_a_move_against_the_profile_the_driver_runs(twin, make):
    """Under a long profile (no setup call: the driver keeps its own, here 4 s), a small move creeps: 0.012 rad
    along the profile's quintic passes the watchdog's 5 mrad only after 1.8 s, past its 1 s margin, and comes
    within the 2 mrad tolerance after 2.8 s. No fault: the step waits for the move
    and ends with it done. A driver that executes nothing is still caught, once the profile and the margin are
    over."""
    stand_in = twin("vx300s", "reach", group_move_s=4.0)
    env = make_real(
        make,
        "VX300SReacherReal-v0",
        stand_in,
        max_episode_steps=3,
        overrides=[
            "robot.ros.setup=[]",
            "robot.ros.arm_command.profile_time_s=4.0",
            "robot.ros.settle.tolerance=0.002",
        ],
    )
    env.reset(seed=0)
    nudge = np.zeros(6, dtype=np.float32)
    nudge[0] = 0.24  # 0.012 rad of waist
    started = time.monotonic()
    _, _, _, truncated, info = env.step(nudge)
    assert "abort_reason" not in info and not truncated
    assert 2.5 < time.monotonic() - started < 5.0 and info["timing"]["motion_s"] > 2.5  # the driver's profile
    twin_waist = stand_in.sim.read_joints().position[stand_in.arm_in_states][0]
    assert twin_waist == pytest.approx(env.unwrapped.state.q_arm[0], abs=0.002)  # read after the motion

    stand_in.faults.ignore_commands = True
    started = time.monotonic()
    _, _, _, truncated, info = env.step(nudge)
    assert truncated and info["abort_reason"].startswith("the arm did not follow the command")
    assert "the 4.00 s its driver was given, plus 1.00 s" in info["abort_reason"]
    assert 5.0 < time.monotonic() - started < 6.0


def test_after_its_profile_a_servo_holds_the_goal_at_its_own_top_speed(twin):
    """xs_sdk at its stock 2 s profile moves the waist 0.4 rad (0.2 rad/s). Pushed back to where it started once
    the profile is over (a cube it presses on, say), the servo's position loop returns it at the motor's top
    speed, as a Dynamixel does after its profile, not at the profile's pace (which would take 2 s again)."""
    import pybullet as p

    stand_in = twin("rx200", "reach")
    sim, waist = stand_in.sim, stand_in.arm_in_states[0]
    start = sim.read_joints().position[stand_in.arm_in_states]
    target = start.copy()
    target[0] += 0.4
    stand_in.driver.move_arm(target, stand_in.group_move_s)
    assert wait_for(lambda: abs(sim.read_joints().position[waist] - target[0]) < 0.01, timeout=4.0)
    time.sleep(0.2)  # the profile is over and the hold has begun
    with sim._lock:
        p.resetJointState(sim.body, sim._arm[0], float(start[0]), 0.0, physicsClientId=sim.client)
    pushed_back = time.monotonic()
    assert wait_for(lambda: abs(sim.read_joints().position[waist] - target[0]) < 0.02, timeout=0.8)
    assert time.monotonic() - pushed_back < 0.8  # at the profile's 0.2 rad/s the way back takes 2 s


# ------------------------------------------------------------------ ur_robot_driver


def test_a_slow_speed_scaling_stretches_the_step_and_a_stalled_one_stops_the_arm(twin, make):
    """The scaled trajectory controller runs a trajectory at the pendant's speed scaling: at 0.4 a step's
    0.2 s motion takes 0.5 s and the step waits for it; at 0.05 it cannot finish within its 0.2 s and the
    margin, and the arm is stopped with the reason."""
    stand_in = twin("ur5e", "reach", speed_scaling=0.4)
    assert published(stand_in, "/speed_scaling_factor") == {"data": 0.4}
    env = make(("UR5eReacherReal-v0"), rosbridge_port=stand_in.port, allow_real_robot_motion=True, max_episode_steps=4)
    env.reset(seed=0)
    nudge = np.zeros(6, dtype=np.float32)
    nudge[0] = 1.0  # 0.05 rad of shoulder pan
    _, _, _, truncated, info = env.step(nudge)
    assert not truncated and 0.45 < info["timing"]["motion_s"] < 1.0
    stand_in.driver.speed_scaling = 0.05
    _, _, _, truncated, info = env.step(-nudge)
    assert truncated and info["abort_reason"].startswith(
        "the arm did not finish the command on /scaled_pos_joint_traj_controller/command within 1.20 s"
    )


# ------------------------------------------------------------------ Niryo ned_ros


def test_a_ned2_connects_with_the_joint_states_of_its_hardware_stack(twin, make):
    stand_in = twin("ned2", "push")
    assert published(stand_in, "/joint_states")["name"] == [f"joint_{i}" for i in range(1, 7)]
    env = make_real(make, "NED2PushReal-v0", stand_in, max_episode_steps=2)
    env.reset(seed=0)
    _, _, _, truncated, info = env.step(np.zeros(6, dtype=np.float32))
    assert "abort_reason" not in info
    # the jaws, which the hardware does not publish, read as the push task's closed gripper (its reset's goal)
    np.testing.assert_allclose(env.unwrapped.state.joint_positions[6:], [-0.01, -0.01])


def test_repeated_ned2_gripper_commands_do_not_queue(twin, make):
    stand_in = twin("ned2", "pnp")
    env = make_real(make, "NED2PnPReal-v0", stand_in, max_episode_steps=12)
    env.reset(seed=0)
    goals_after_reset = len(on(stand_in, NED2_GOALS))
    action = np.zeros(7, dtype=np.float32)
    action[-1] = 0.008  # open, as the reset left it: nothing to send
    for _ in range(4):
        env.step(action)
    assert len(on(stand_in, NED2_GOALS)) == goals_after_reset
    action[-1] = -0.009  # close, then keep asking for it
    started = time.monotonic()
    env.step(action)
    closed_in = time.monotonic() - started
    for _ in range(3):
        env.step(action)
    assert len(on(stand_in, NED2_GOALS)) == goals_after_reset + 1 and stand_in.driver.queued == 0
    assert finger(stand_in) < -0.009 and closed_in < 2.5  # the close ran at once, not behind a queue


def test_a_ned2_gripper_goal_the_driver_aborts_ends_the_episode_with_its_words(twin, make):
    stand_in = twin("ned2", "pnp")
    env = make_real(make, "NED2PnPReal-v0", stand_in, max_episode_steps=6)
    env.reset(seed=0)
    stand_in.driver.mounted_tool = 12  # Gripper 2 is mounted: the env's goals name Gripper 1 (11)
    settled(stand_in, quiet=0.1)
    action = np.zeros(7, dtype=np.float32)
    action[-1] = -0.01
    _, _, _, truncated, info = env.step(action)
    assert truncated
    assert info["abort_reason"] == (
        f"the gripper goal on {NED2_GOALS} ended ABORTED: status -251, "
        "message 'Tools ID do not match -> Given : 11 Expected : 12'"
    )
    stand_in.driver.mounted_tool = 11
    env.reset(seed=1)  # recovered: the next episode's goals succeed
    _, _, _, truncated, info = env.step(action)
    assert "abort_reason" not in info and finger(stand_in) < -0.009


# ------------------------------------------------------------------ a step means one thing


def _episodes(env, seeds, policy_of):
    rows = []
    for seed in seeds:
        observation, _ = env.reset(seed=seed)
        policy = policy_of(env)
        for length in range(1, env.spec.max_episode_steps + 1):
            observation, _, terminated, truncated, info = env.step(policy(observation))
            assert "abort_reason" not in info, info["abort_reason"]
            if terminated or truncated:
                break
        rows.append((bool(info["is_success"]), length))
    return rows


def test_a_policy_from_simulation_keeps_its_success_on_the_real_id_at_stock_timing(twin, make):
    """The scripted expert on VX300S Reach, sim against the twin of xs_sdk at its stock 2 s profile (the env
    sets its own through the operating-modes service): the same goals are reached, in as many steps (at most
    1.5 times), with no watchdog abort."""
    seeds = [3, 11]
    sim = make("VX300SReacherGoalSim-v0", max_episode_steps=25)
    simulated = _episodes(sim, seeds, lambda env: make_policy("scripted", env))
    stand_in = twin("vx300s", "reach")
    real = make(
        "VX300SReacherGoalReal-v0", rosbridge_port=stand_in.port, allow_real_robot_motion=True, max_episode_steps=25
    )
    on_twin = _episodes(real, seeds, lambda env: make_policy("scripted", env))
    assert [success for success, _ in simulated] == [True, True]
    assert sum(s for s, _ in on_twin) >= 0.9 * sum(s for s, _ in simulated)
    for (_, sim_length), (_, real_length) in zip(simulated, on_twin):
        assert real_length <= 1.5 * sim_length, (simulated, on_twin)
    assert stand_in.server.errors == []


def test_the_ned2_grasp_threshold_lies_between_a_held_cube_and_niryos_open():
    """A real Ned2's open goal leaves the jaws at Niryo's own open position (its SRDF's named state, 0.007 m),
    which must not read as closed on a cube; a cube the jaws hold must. Measured on the simulated expert's lift."""
    from envfactory.twin.drivers import NIRYO_JAWS

    env = gym.make("NED2PnPSim-v0")
    threshold = env.unwrapped.blueprint.spec.robot.gripper.grasp_threshold
    policy = make_policy("scripted", env)
    held = []
    observation, _ = env.reset(seed=0)
    spawn_z = env.unwrapped.state.objects["cube"].position[2]
    for _ in range(80):
        observation, _, terminated, truncated, info = env.step(policy(observation))
        state = env.unwrapped.state
        if state.objects["cube"].position[2] > spawn_z + 0.02:  # lifted: the jaws hold it
            held.append(state.gripper)
        if terminated or truncated:
            break
    env.close()
    assert len(held) >= 3, "the expert never lifted the cube"
    assert max(held) < threshold < NIRYO_JAWS[1], (max(held), threshold)


@pytest.mark.parametrize("robot, env_id", [("vx300s", "VX300SPnPSim-v0"), ("rx200", "RX200PnPSim-v0")])
@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_a_simulator_reads_the_gripper_as_xs_sdk_publishes_it(twin, robot, env_id, engine):
    """The horn angle xs_sdk publishes as `gripper`, and its zero finger velocities, in simulation too: the
    columns a policy trained there reads on the real arm. Judged by the twin's xs_sdk (the maker's linkage)."""
    driver = twin(robot, "pnp").driver
    env = gym.make(env_id, engine=engine)
    env.reset(seed=0)
    names = env.unwrapped.blueprint.spec.robot.state_names
    for value in (0.0, 0.02, 0.02, 0.02):  # closing: the fingers move, then rest
        action = np.zeros(env.action_space.shape, dtype=np.float32)
        action[-1] = value or env.unwrapped.blueprint.spec.robot.gripper.open
        env.step(action)
        state = env.unwrapped.state
        finger = state.joint_positions[names.index("left_finger")]
        assert state.joint_positions[names.index("gripper")] == pytest.approx(driver.horn_angle(2 * finger), abs=1e-9)
        assert (
            state.joint_velocities[names.index("left_finger")]
            == state.joint_velocities[names.index("right_finger")]
            == 0.0
        )
    env.close()


# ------------------------------------------------------------------ the twin's stand-in for a person


def call_service(stand_in, service, args):
    """One service call as a bare rosbridge client makes it: the server's answer."""
    with connect(f"ws://127.0.0.1:{stand_in.port}") as websocket:
        websocket.send(json.dumps({"op": "call_service", "service": service, "args": args, "id": "1"}))
        while True:
            message = json.loads(websocket.recv(timeout=5.0))
            if message.get("op") == "service_response":
                return message


def test_the_twin_puts_the_cube_back_where_it_is_asked_as_a_person_would(twin, make):
    """Between real episodes a person puts the cube back; the twin's place_object service does it, and the Real
    ID reads the cube there, at rest on the table. Anything else is refused with the reason."""
    from envfactory.twin.twin import PLACE_SERVICE, place_object

    stand_in = twin("ur5e", "push")
    env = make_real(make, "UR5ePushReal-v0", stand_in)
    env.reset(seed=0)
    spawn = np.array(stand_in.spec.task.objects["cube"].spawn.position)
    where = spawn + [-0.06, 0.08, 0.0]
    assert call_service(stand_in, PLACE_SERVICE, {"name": "cube", "position": list(where)})["result"] is True
    time.sleep(0.5)  # the tracker publishes at 30 Hz
    read = env.unwrapped.backend.read_object("cube").position
    assert np.allclose(read, where, atol=2e-3), (read, where)
    for args, reason in [
        ({"name": "ball", "position": list(where)}, "no object 'ball' in the task (it has ['cube'])"),
        ({"name": "cube", "position": [0.5, 0.1]}, "is not a task-frame point x, y, z"),
    ]:
        assert call_service(stand_in, PLACE_SERVICE, args)["result"] is False
        assert any(reason in error for error in stand_in.server.errors), stand_in.server.errors
    with pytest.raises(RuntimeError, match=r"did not place ball at \[0\.5, 0\.1, 0\.8\]"):
        place_object(stand_in.port, "ball", [0.5, 0.1, 0.8])  # the client a benchmark or rehearsal script calls


def test_the_twin_brings_the_arm_clear_by_hand_when_asked_as_a_person_would(twin, make):
    """When the env refuses to drive a real arm home ("bring the arm clear by hand"), a person moves it in
    freedrive; the twin's place_arm service does it, the Real ID reads the arm there a second later, and its next
    reset drives home from there. Anything else is refused with the reason."""
    from envfactory.twin.twin import ARM_SERVICE, place_arm

    stand_in = twin("ur5e", "push")
    env = make_real(make, "UR5ePushReal-v0", stand_in)
    env.reset(seed=0)
    home = np.array(stand_in.spec.robot.home, float)
    where = home + [0.3, -0.2, 0.1, 0.0, 0.2, -0.4]
    place_arm(stand_in.port, where, 0.3)
    time.sleep(1.0)
    backend = env.unwrapped.backend
    reading = backend.read_joints().position
    assert np.allclose(reading[env.unwrapped._arm_in_states], where, atol=2e-3), (reading, where)
    assert abs(reading[env.unwrapped._gripper_in_states] - 0.3) < 2e-3
    env.reset(seed=1)  # and the env drives it home from there
    assert np.allclose(backend.read_joints().position[env.unwrapped._arm_in_states], home, atol=0.02)
    for args, reason in [
        ({"position": [0.0] * 5, "gripper": 0.3}, "is not one value for each of the 6 arm joints"),
        ({"position": list(home + [0, 0, 0, 0, 0, 9.0]), "gripper": 0.3}, "outside the limits of ['wrist_3_joint']"),
        ({"position": list(home), "gripper": 1.5}, "gripper 1.5 lies outside its range [0.0, 0.8]"),
    ]:
        assert call_service(stand_in, ARM_SERVICE, args)["result"] is False
        assert any(reason in error for error in stand_in.server.errors), stand_in.server.errors
    with pytest.raises(RuntimeError, match=r"did not place the arm at \[0\.0, 0\.0, 0\.0, 0\.0, 0\.0\]"):
        place_arm(stand_in.port, [0.0] * 5, 0.3)
