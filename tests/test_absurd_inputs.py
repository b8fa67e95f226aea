"""Inputs a user hands the env or the tools that used to run silently or crash from deep inside: each is now a
message that names what was wrong and where."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.error import ClosedEnvironmentError

import envfactory  # noqa: F401  (registers the IDs)


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


def _expert_run(engine: str, overrides: list[str], episodes: int = 2) -> tuple[list[dict], int]:
    """The last info of each of the Push expert's episodes on the VX300S, and how many left the physics."""
    from envfactory.experts import make_policy

    env = gym.make("VX300SPushSim-v0", engine=engine, randomize=True, overrides=overrides)
    policy, infos = make_policy("scripted", env), []
    for seed in range(episodes):
        observation, _ = env.reset(seed=seed)
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
    """A damping at the top of its bound (100 N m s/rad) makes PyBullet joints read about 100 rad/s, 30 times
    the VX300S's limits: the episode ends there, counted, instead of an observation clipped to look valid."""
    infos, breaks = _expert_run("pybullet", ["task.randomization.events.arm_damping.params.range=[100,100]"])
    for info in infos:
        assert info["abort_reason"].startswith("the simulation left its limits: joint "), info.get("abort_reason")
        assert "rad/s, over 4 times its declared velocity bound (3.15 rad/s)" in info["abort_reason"]
    assert breaks == len(infos)


def test_the_shipped_randomization_stays_within_the_physics():
    """The shipped damping range (0 to 0.5) never trips the check, on either engine."""
    for engine in ("pybullet", "mujoco"):
        infos, breaks = _expert_run(engine, [])
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
    from envfactory.factory import blueprint
    from envfactory.schema.errors import SpecError

    with pytest.raises(SpecError) as caught:
        blueprint("VX300SPushSim-v0", [override], randomize=True)
    message = " ".join(str(caught.value).split())
    assert f"override '{override}'" in message and complaint in message, message
    blueprint("VX300SPushSim-v0", ["+task.randomization.events.arm_damping.every={seconds: 0.5}"], randomize=True)


def test_a_mass_range_typed_in_grams_is_refused_against_the_robots_payload_naming_the_override():
    """[50, 90] meant grams: as kilograms the cube would weigh up to 90 kg in a 4 cm box (the expert then fails
    every episode). The VX300S is rated for 0.75 kg; the error names the override that wrote the range."""
    from envfactory.factory import blueprint
    from envfactory.schema.errors import SpecError

    typed = "+task.randomization.events.cube_mass.params.range=[50,90]"
    with pytest.raises(SpecError) as caught:
        blueprint("VX300SPushSim-v0", ["~task.randomization.events.cube_mass.params.scale", typed], randomize=True)
    message = " ".join(str(caught.value).split())
    assert f"override '{typed}': task.randomization.events.cube_mass: samples up to 90 kg" in message, message
    assert "rated payload of 0.75 kg (robot.payload); looks like grams" in message
    with pytest.raises(SpecError, match=r"task.objects.cube.mass: weighs 2 kg, over robot rx200's rated payload"):
        blueprint("RX200PushSim-v0", ["task.objects.cube.mass=2"])
