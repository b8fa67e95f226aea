"""Faults on the real path, each followed by an episode that runs: a malformed joint state,
the server killed and back, a frozen driver, a command topic of another type, a controller
that executes nothing. Proven by what the twin's arm received over a loopback socket:
the exact commands, one stop per event, nothing after a gate."""

import numpy as np
import pytest
from real_helpers import (
    NED2_ARM,
    NED2_JOINTS,
    UR5E_ARM,
    UR5E_JOINTS,
    VX300S_ARM,
    VX300S_JOINTS,
    is_stop,
    make_real,
    on,
    settled,
    wait_for,
)

from envfactory.backends.base import CommandRefused, ConnectionLost

ROBOTS = {  # robot -> (env ID, arm command topic, joint states topic)
    "ur5e": ("UR5eReacherReal-v0", UR5E_ARM, UR5E_JOINTS),
    "vx300s": ("VX300SReacherReal-v0", VX300S_ARM, VX300S_JOINTS),
    "ned2": ("NED2ReacherReal-v0", NED2_ARM, NED2_JOINTS),
}
TRAJECTORIES = ("ur5e", "ned2")  # trajectory controllers: their stop is the empty trajectory
NUDGE = np.array([0.6, 0.0, 0.0, 0.0, 0.0, 0.0], dtype=np.float32)  # a small waist move (delta action)


def start(twin, make, robot, **env_kwargs):
    # the xs_sdk stand-in takes 0.1 s per group command here (its real default profile: 2 s)
    stand_in = twin(robot, "reach", group_move_s=0.1)
    env_id, arm, joints = ROBOTS[robot]
    env = make_real(make, env_id, stand_in, **env_kwargs)
    env.reset(seed=0)
    return stand_in, env, arm, joints


def play(env, steps=3, seed=None):
    """An episode that runs: a reset, then steps that all go through."""
    env.reset(seed=seed)
    for _ in range(steps):
        _, _, _, truncated, info = env.step(NUDGE * (1 if _ % 2 == 0 else -1))
        assert "abort_reason" not in info and not truncated, info.get("abort_reason")


def arm_position(stand_in):
    return stand_in.sim.read_joints().position[stand_in.arm_in_states]


def assert_one_hold(stand_in, robot, after):
    """Exactly one message reached the arm since `after`, and it holds the arm where it is."""
    received = on(stand_in, ROBOTS[robot][1])[after:]
    assert len(received) == 1, received
    if robot in TRAJECTORIES:
        assert is_stop(received[0])  # the trajectory controller's own stop
    else:
        np.testing.assert_allclose(received[0]["cmd"], arm_position(stand_in), atol=0.02)


@pytest.mark.parametrize("robot", ROBOTS)
def test_one_malformed_joint_state_ends_the_episode_and_the_next_one_runs(twin, make, robot):
    stand_in, env, arm, joints = start(twin, make, robot)
    env.step(NUDGE)
    stand_in.faults.corrupt(joints, 1)  # one NaN position, sent as null, then good ones again
    assert wait_for(lambda: stand_in.faults.malformed[joints] == 0)
    settled(stand_in, quiet=0.15)
    sent = len(on(stand_in, arm))
    _, _, terminated, truncated, info = env.step(NUDGE)
    assert truncated and not terminated
    assert info["abort_reason"].startswith(f"malformed message on {joints}") and "null" in info["abort_reason"]
    settled(stand_in, quiet=0.15)
    assert_one_hold(stand_in, robot, sent)
    play(env, seed=1)  # the fault was cleared: it does not poison this episode


@pytest.mark.parametrize("robot", ROBOTS)
def test_the_server_killed_mid_episode_comes_back_and_the_next_episode_runs(twin, make, robot):
    stand_in, env, arm, _ = start(twin, make, robot)
    env.step(NUDGE)
    settled(stand_in, quiet=0.15)
    sent = len(on(stand_in, arm))
    stand_in.kill(down_for=1.0)
    with pytest.raises(ConnectionLost, match="lost the rosbridge connection"):
        for _ in range(10):
            env.step(NUDGE)
    env.reset(seed=1)  # reconnects with backoff, then drives home
    settled(stand_in, quiet=0.15)
    received = on(stand_in, arm)[sent:]
    if robot in TRAJECTORIES:
        assert is_stop(received[0]) and not any(is_stop(m) for m in received[1:])  # the owed stop, once
        assert received[1]["points"][0]["time_from_start"]["secs"] >= 1  # then the drive home
    else:  # the owed hold where the arm stands, then the drive home in segments
        np.testing.assert_allclose(received[0]["cmd"], received[1]["cmd"], atol=0.1)
        np.testing.assert_allclose(received[-1]["cmd"], env.unwrapped.home, atol=1e-6)
    play(env, seed=2)


@pytest.mark.parametrize("robot", ROBOTS)
def test_a_frozen_driver_ends_the_episode_as_stale_and_reset_waits_for_it(twin, make, robot):
    stand_in, env, arm, joints = start(twin, make, robot)
    env.step(NUDGE)
    stand_in.faults.silence(joints, 1.2)
    for _ in range(20):
        sent = len(on(stand_in, arm))
        last = on(stand_in, arm)[-1]
        _, _, _, truncated, info = env.step(NUDGE)
        if truncated:
            break
    assert info["abort_reason"].startswith(f"{joints} is stale: newest message ")
    assert "s old (limit 0.50 s)" in info["abort_reason"]
    settled(stand_in, quiet=0.15)
    # the aborted step's own command if it went out while the reading was still fresh, then one stop
    received = on(stand_in, arm)[sent:]
    assert 1 <= len(received) <= 2
    stop, last_motion = received[-1], (received[:-1] or [last])[-1]
    if robot in TRAJECTORIES:
        assert is_stop(stop) and not any(map(is_stop, received[:-1]))
    else:  # no fresh reading to hold at: the last target, never the stale reading
        assert stop == last_motion
    play(env, seed=1)  # reset waits for the driver to come back


def test_a_command_topic_of_another_type_is_refused_at_connect(twin, make):
    stand_in = twin("ur5e", "reach", topic_types={UR5E_ARM: "std_msgs/Float64MultiArray"})
    with pytest.raises(CommandRefused) as refused:
        make_real(make, "UR5eReacherReal-v0", stand_in)
    assert (
        f"{UR5E_ARM} has type std_msgs/Float64MultiArray on the robot, but this env sends "
        f"trajectory_msgs/JointTrajectory there"
    ) in str(refused.value)
    assert stand_in.received == []

    vx = twin("vx300s", "reach")  # a topic map that points the arm at the gripper's topic
    with pytest.raises(
        CommandRefused,
        match="/vx300s/commands/joint_single has type "
        "interbotix_xs_msgs/JointSingleCommand on the robot, but this env "
        "sends interbotix_xs_msgs/JointGroupCommand",
    ):
        make_real(make, "VX300SReacherReal-v0", vx, arm_command_topic="/vx300s/commands/joint_single")
    assert vx.received == []


def test_without_rosapi_a_refused_command_is_caught_by_the_watchdog(twin, make):
    stand_in = twin("ur5e", "reach", topic_types={UR5E_ARM: "std_msgs/Float64MultiArray"})
    stand_in.faults.no_rosapi = True  # nothing to check with at connect
    env = make_real(make, "UR5eReacherReal-v0", stand_in)
    env.reset(seed=0)
    for _ in range(30):
        _, _, _, truncated, info = env.step(NUDGE)
        if truncated:
            break
    assert info["abort_reason"].startswith(f"the arm did not follow the command on {UR5E_ARM}")
    assert stand_in.received == []  # the server refused every command (only in its own log)
    assert any("std_msgs/Float64MultiArray" in error for error in stand_in.server.errors)


@pytest.mark.parametrize("robot", TRAJECTORIES)  # the VX300S's: tests/test_real_drivers.py, under a long profile
def test_a_controller_that_executes_nothing_is_caught_and_the_next_episode_runs(twin, make, robot):
    stand_in, env, arm, _ = start(twin, make, robot)
    stand_in.faults.ignore_commands = True
    for _ in range(30):
        _, _, _, truncated, info = env.step(NUDGE)
        if truncated:
            break
    assert info["abort_reason"].startswith(f"the arm did not follow the command on {arm}")
    settled(stand_in, quiet=0.15)
    received = on(stand_in, arm)
    assert is_stop(received[-1]) and sum(map(is_stop, received)) == 1
    stand_in.faults.ignore_commands = False
    play(env, seed=1)


def test_vx300s_drives_home_in_segments_no_faster_than_reset_speed(twin, make):
    stand_in = twin("vx300s", "reach", group_move_s=0.05)
    env = make_real(make, "VX300SReacherReal-v0", stand_in, delta_action=False)
    env.reset(seed=0)
    home = np.asarray(env.unwrapped.home)
    away = home + np.array([0.45, 0.0, 0.0, 0.0, 0.0, 0.0])
    _, _, _, _, info = env.step(away.astype(np.float32))
    assert info["action_rejected"] == 0.0
    assert wait_for(lambda: np.allclose(arm_position(stand_in), away, atol=0.01))
    settled(stand_in, quiet=0.15)
    sent = len(on(stand_in, VX300S_ARM))
    env.reset(seed=1)
    settled(stand_in, quiet=0.15)
    targets = np.array([m["cmd"] for m in on(stand_in, VX300S_ARM)[sent:]])
    # each segment lasts the time profile the env set in the driver at connect (xs_sdk's own is 2 s)
    reset_speed, segment_s = 0.3, stand_in.group_move_s
    assert segment_s < 2.0 and segment_s == pytest.approx(env.unwrapped.backend.motion_s, abs=1e-3)
    assert len(targets) == int(np.ceil(0.45 / reset_speed / segment_s))  # 1.5 s in segments of the profile
    steps = np.abs(np.diff(np.vstack([away, targets]), axis=0)).max(axis=1)
    assert np.all(steps <= reset_speed * segment_s + 1e-6)
    np.testing.assert_allclose(targets[-1], home, atol=1e-6)


def run_cli(stand_in, *extra):
    from typer.testing import CliRunner

    from envfactory.cli.app import app

    command = [
        "run",
        "UR5eReacherReal-v0",
        "-n",
        "3",
        "--policy",
        "random",
        "--allow-real-robot-motion",
        "-k",
        f"rosbridge_port={stand_in.port}",
        "-k",
        "max_episode_steps=10",
        *[arg for name, value in FAST_KWARGS.items() for arg in ("-k", f"{name}={value}")],
        *extra,
    ]
    return CliRunner().invoke(app, command)


FAST_KWARGS = {"action_cycle_time": 0.1, "environment_loop_rate": 10.0, "action_speed": 0.05}


def inject_after(stand_in, commands, fault):
    """Run `fault` once the arm has received `commands` commands (from a helper thread)."""
    import threading

    def watch():
        if wait_for(lambda: len(on(stand_in, UR5E_ARM)) >= commands, timeout=30):
            fault()

    thread = threading.Thread(target=watch, daemon=True)
    thread.start()
    return thread


def home_drives(stand_in):
    return [m for m in on(stand_in, UR5E_ARM) if m["points"] and m["points"][0]["time_from_start"]["secs"] >= 1]


def test_run_goes_on_after_a_fault_and_prints_every_episode(twin):
    stand_in = twin("ur5e", "reach")
    inject_after(stand_in, 3, lambda: stand_in.faults.silence(UR5E_JOINTS, 1.0))  # home, 2 steps, then frozen
    result = run_cli(stand_in)
    assert result.exit_code == 0, result.output
    assert "1 aborted by a fault" in result.output and "stale" in result.output
    assert result.output.count("│ no ") + result.output.count("│ yes ") == 3  # three rows
    assert len(home_drives(stand_in)) == 3  # one drive home per episode, none before the first
    assert wait_for(lambda: is_stop(on(stand_in, UR5E_ARM)[-1]))  # the stop at close
    settled(stand_in, quiet=0.15)
    assert sum(map(is_stop, on(stand_in, UR5E_ARM))) == 2  # that one and the fault's, no more


def test_run_prints_the_table_when_recovery_fails(twin):
    stand_in = twin("ur5e", "reach")

    def gone_for_good():
        stand_in.faults.refuse_connections = True
        stand_in.drop_connections()

    inject_after(stand_in, 3, gone_for_good)
    result = run_cli(stand_in, "-o", "env.real.reconnect_tries=2")
    assert result.exit_code == 1
    assert "the run stopped after 1 of 3 episodes" in result.output and "2 connection tries" in result.output
    assert "lost the rosbridge connection" in result.output  # the aborted episode's reason, in the table
