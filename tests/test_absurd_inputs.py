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
