"""The PnP experts hold success to the episode's end: on Dense IDs the episode runs on after the goal is
reached, and a dataset's demonstration should end successful. Judged by the env's own success at the last
step of whole episodes."""

from __future__ import annotations

import gymnasium as gym
import pytest

import envfactory  # noqa: F401  (registers the IDs)
from envfactory.experts import make_policy


@pytest.mark.parametrize("env_id", ["UR5ePnPSim-v0", "VX300SPnPSim-v0"])
def test_pnp_experts_end_their_episodes_successful(env_id):
    env = gym.make(env_id)
    policy = make_policy("scripted", env)
    ends = []
    try:
        for seed in (0, 1, 2):
            observation, _ = env.reset(seed=seed)
            policy.reset()
            while True:
                observation, _, terminated, truncated, info = env.step(policy(observation))
                if terminated or truncated:
                    break
            ends.append(bool(info["is_success"]))
    finally:
        env.close()
    assert all(ends), ends
