"""Inputs a user hands the env or the tools that used to run silently or crash from deep inside: each is now a
message that names what was wrong and where."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.error import ClosedEnvironmentError

import envfactory  # noqa: F401  (registers the IDs)
from envfactory.factory import blueprint
from envfactory.schema.errors import SpecError


def refusal(env_id: str, overrides: list[str], **kwargs) -> str:
    """The message compiling `env_id` with these overrides and kwargs is refused with, on one line."""
    with pytest.raises(SpecError) as caught:
        blueprint(env_id, overrides, **kwargs)
    return " ".join(str(caught.value).split())


@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_a_closed_env_says_so_on_step_and_reset(engine):
    env = gym.make("UR5eReacherSim-v0", engine=engine)
    env.reset(seed=0)
    env.close()
    with pytest.raises(ClosedEnvironmentError, match=r"UR5eReacherSim-v0\.step\(\) after close\(\)"):
        env.step(env.action_space.sample())
    with pytest.raises(ClosedEnvironmentError, match=r"UR5eReacherSim-v0\.reset\(\) after close\(\)"):
        env.reset(seed=1)


@pytest.mark.parametrize(
    "goal, complaint",
    [
        ([0.5, 0.1], r"a goal is 3 numbers x, y, z \(task frame, m\), got shape \(2,\)"),
        ([0.5, float("nan"), 0.2], r"is not finite"),
        ([17.0, 0.0, 0.2], r"lies outside the goal box \[.*\] \.\. \[.*\] \(task\.goal\.box"),
        ("here", r"'here' is not a point"),
    ],
)
def test_a_chosen_goal_is_refused_unless_it_is_a_point_of_the_goal_box(goal, complaint):
    env = gym.make("UR5eReacherGoalSim-v0")
    with pytest.raises(ValueError, match=r'UR5eReacherGoalSim-v0\.reset\(options=\{"goal": \.\.\.\}\): .*' + complaint):
        env.reset(seed=0, options={"goal": goal})
    env.close()


def test_a_chosen_goal_inside_the_box_is_the_episodes_goal():
    env = gym.make("UR5eReacherGoalSim-v0")
    low, high = (np.asarray(bound, float) for bound in env.unwrapped.blueprint.spec.task.goal.box)
    chosen = (low + high) / 2
    observation, _ = env.reset(seed=0, options={"goal": chosen.tolist()})
    np.testing.assert_allclose(env.unwrapped.goal, chosen)
    np.testing.assert_allclose(observation["desired_goal"], chosen, atol=1e-6)
    env.close()


def _expert_run(engine: str, episodes: int = 2, forced_damping: float | None = None) -> tuple[list[dict], int]:
    """The last info of each of the Push expert's episodes on the VX300S, and how many left the physics.
    `forced_damping` is set on the engine itself after each reset, past what a spec may declare."""
    from envfactory.experts import make_policy
    from envfactory.step_state import PhysicsChange

    env = gym.make("VX300SPushSim-v0", engine=engine, randomize=True)
    policy, infos = make_policy("scripted", env), []
    for seed in range(episodes):
        observation, _ = env.reset(seed=seed)
        if forced_damping is not None:
            env.unwrapped.backend.apply_physics(PhysicsChange("arm_damping", "", forced_damping))
        policy.reset()
        done = False
        while not done:
            observation, _, terminated, truncated, info = env.step(policy(observation))
            done = terminated or truncated
        infos.append(info)
    breaks = env.unwrapped.sim_limits.breaks
    env.close()
    return infos, breaks


def test_a_simulation_that_leaves_its_physics_ends_the_episode_with_the_reason():
    """A damping of 100 N m s/rad (which a spec may not declare for the VX300S: see below) makes PyBullet joints
    read about 100 rad/s, 30 times the VX300S's limits, and flings the cube out of the scene: the episode ends
    there, counted, instead of an observation clipped to look valid."""
    infos, breaks = _expert_run("pybullet", forced_damping=100.0)
    for info in infos:
        reason = info.get("abort_reason", "")
        assert reason.startswith("the simulation left its limits: "), reason
        assert "over 4 times its declared velocity bound (3.15 rad/s)" in reason or "out of the scene" in reason
    assert breaks == len(infos)


def test_the_shipped_randomization_stays_within_the_physics():
    """The shipped damping range (0 to 0.5) never trips the check, on either engine."""
    for engine in ("pybullet", "mujoco"):
        infos, breaks = _expert_run(engine)
        assert breaks == 0 and not any("abort_reason" in info for info in infos), (engine, infos)


@pytest.mark.parametrize(
    "override, complaint",
    [
        (
            "+task.randomization.events.more_damping={term: arm_damping, params: {range: [0.0, 0.2]}}",
            "task.randomization.events.more_damping: sets arm_damping, as event 'arm_damping' does",
        ),
        (
            "+task.randomization.events.cube_mass_again={term: object_mass, params: {object: cube, range: [0.1, 0.2]}}",
            "sets object_mass of cube, as event 'cube_mass' does",
        ),
        (
            "+task.randomization.events.arm_damping.every={seconds: 0.1}",
            "every 0.1 s is shorter than the action cycle (0.5 s)",
        ),
    ],
)
def test_events_that_the_engine_cannot_keep_are_refused_naming_the_override(override, complaint):
    message = refusal("VX300SPushSim-v0", [override], randomize=True)
    assert f"override '{override}'" in message and complaint in message, message
    blueprint("VX300SPushSim-v0", ["+task.randomization.events.arm_damping.every={seconds: 0.5}"], randomize=True)


@pytest.mark.parametrize(
    "env_id, high, complaint",
    [
        (
            "VX300SPushSim-v0",
            100,
            "arm_damping up to 100 N m s/rad would take 314 N m from joint waist at its rated speed of 3.14 rad/s, "
            "over its rated effort of 20 N m (the robot's URDF limits): its motor could never drive it; for robot "
            "vx300s, at most 6.37 N m s/rad",
        ),
        (  # the RX200's light wrist: PyBullet's joints blow up at 2 (31 rad/s measured)
            "RX200PushSim-v0",
            2,
            "would take 6.28 N m from joint wrist_angle at its rated speed of 3.14 rad/s",
        ),
        ("RX200PushSim-v0", 0.5, "from joint wrist_rotate"),  # the shipped tasks' 0.5: the RX200 families cap it
    ],
)
def test_a_damping_its_motors_could_not_drive_through_is_refused(env_id, high, complaint):
    override = f"task.randomization.events.arm_damping.params.range=[0,{high}]"
    message = refusal(env_id, [override])
    assert f"override '{override}'" in message and complaint in message, message
    assert blueprint("RX200PushSim-v0", randomize=True).events  # the RX200 families' own range, 0 to 0.3


def test_a_mass_range_typed_in_grams_is_refused_against_the_robots_payload_naming_the_override():
    """[50, 90] meant grams: as kilograms the cube would weigh up to 90 kg in a 4 cm box (the expert then fails
    every episode). The VX300S is rated for 0.75 kg; the error names the override that wrote the range."""
    typed = "+task.randomization.events.cube_mass.params.range=[50,90]"
    message = refusal("VX300SPushSim-v0", ["~task.randomization.events.cube_mass.params.scale", typed], randomize=True)
    assert f"override '{typed}': task.randomization.events.cube_mass: samples up to 90 kg" in message, message
    assert "rated payload of 0.75 kg (robot.payload); looks like grams" in message
    with pytest.raises(SpecError, match=r"task.objects.cube.mass: weighs 2 kg, over robot rx200's rated payload"):
        blueprint("RX200PushSim-v0", ["task.objects.cube.mass=2"])


@pytest.mark.parametrize(
    "override, complaint",
    [
        (  # 0.5 rad of encoder noise: the UR5e joint columns span 4π, 1% of which is 0.126 rad
            "task.randomization.sensing.joint_noise.params.std=0.5",
            "noise spreading 0.5 (std 0.5, bias_std 0, drift_std 0 over 100 steps) on 'joint_positions' (rad) is "
            "over 1% of its columns' typical range (12.6): at most 0.126",
        ),
        (  # half a metre of cube-tracker error
            "task.randomization.sensing.cube_noise.params.std=0.5",
            "on 'object_position' (m) is over 1% of its columns' typical range (2.41): at most 0.0241",
        ),
        (  # a drift that walks 10 cm over the episode
            "+task.randomization.sensing.cube_noise.params.drift_std=0.01",
            "drift_std 0.01 over 100 steps) on 'object_position' (m)",
        ),
    ],
)
def test_noise_is_judged_against_the_range_of_the_observation_it_blurs(override, complaint):
    message = refusal("UR5ePushSim-v0", [override], randomize=True)
    assert f"override '{override}'" in message and complaint in message, message


def test_the_shipped_noise_is_plausible_on_every_robot():
    for env_id in ("UR5ePushSim-v0", "VX300SPnPSim-v0", "RX200ReacherSim-v0", "NED2PushSim-v0"):
        assert blueprint(env_id, randomize=True).sensing


@pytest.mark.parametrize(
    "override, engine, complaint",
    [
        (  # PyBullet's rate on a MuJoCo make
            "sim.physics_hz=2000",
            "mujoco",
            "sim.physics_hz: only pybullet reads sim.physics_hz, and this ID runs on mujoco (its own is "
            "sim.mujoco.physics_hz): the value would go unused",
        ),
        (  # MuJoCo's rate on a PyBullet make
            "sim.mujoco.physics_hz=1000",
            None,
            "only mujoco reads sim.mujoco.physics_hz, and this ID runs on pybullet (its own is sim.physics_hz)",
        ),
        (
            "sim.motor_position_gain=0.5",
            "mujoco",
            "only pybullet reads sim.motor_position_gain, and this ID runs on mujoco:",
        ),
    ],
)
def test_a_setting_for_this_make_that_its_engine_never_reads_is_refused(override, engine, complaint):
    message = refusal("UR5ePushSim-v0", [override], **({} if engine is None else {"engine": engine}))
    assert complaint in message and f"override '{override}'" in message, message


def test_a_family_that_writes_both_engines_settings_serves_both(tmp_path):
    """The shipped families write MuJoCo's rate (and the RX200's PyBullet solver iterations) beside the other
    engine's: the engine kwarg picks one, and neither make is refused."""
    for engine in ("pybullet", "mujoco"):
        assert blueprint("RX200PushSim-v0", engine=engine).backend == engine
        assert blueprint("UR5ePushSim-v0", engine=engine).backend == engine


def test_a_family_that_chooses_an_engine_and_writes_only_the_others_rate_is_refused(tmp_path):
    """`engine: mujoco` beside `physics_hz: 2000` (PyBullet's): the rate would be silently unused."""
    from test_silent_mistakes import line_of, user_folder
    from test_silent_mistakes import refusal as folder_refusal

    folder = user_folder(
        tmp_path,
        "ur5e_push",
        edits=[("specs/ur5e_push.yaml", "  mujoco: {physics_hz: 320}", "  engine: mujoco\n  physics_hz: 2000")],
    )
    family = folder / "specs" / "ur5e_push.yaml"
    message = folder_refusal(folder)
    assert f"{family}:{line_of(family, 'physics_hz: 2000')}" in message, message
    assert "sim.physics_hz: only pybullet reads sim.physics_hz, and this ID runs on mujoco" in message
