"""gym.make_vec in async mode: every env in its own process, stepping in lockstep."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import envfactory

SIM_IDS = sorted(i for i, r in envfactory.records().items() if r.backend == "sim")


def step_async(env_id: str, num_envs: int = 2, steps: int = 3) -> None:
    envs = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="async")
    try:
        single = gym.make(env_id)
        observations, _ = envs.reset(seed=0)
        first, _ = single.reset(seed=0)  # sub-env 0 is seeded 0, as this env is
        single.close()
        for key in first if isinstance(first, dict) else {None: first}:
            ours = observations[key][0] if key is not None else observations[0]
            theirs = first[key] if key is not None else first
            assert np.array_equal(ours, theirs), f"{env_id}: sub-env 0 does not start as a seed-0 env does ({key})"
        envs.action_space.seed(0)
        for _ in range(steps):
            observations, rewards, terminated, truncated, infos = envs.step(envs.action_space.sample())
            assert rewards.shape == (num_envs,) and np.all(np.isfinite(rewards))
        assert envs.observation_space.contains(observations)
    finally:
        envs.close()


@pytest.mark.parametrize("env_id", ["VX300SPushSim-v0", "UR5ePnPGoalSim-v0"])
def test_async_vector_env_steps(env_id):
    step_async(env_id)


@pytest.mark.slow
@pytest.mark.parametrize("env_id", SIM_IDS)
def test_async_vector_env_steps_for_every_id(env_id):
    step_async(env_id)
