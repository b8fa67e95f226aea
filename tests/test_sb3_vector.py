"""SB3VectorEnv: Stable-Baselines3 on the native vector env, judged against SB3's own DummyVecEnv over gym.make
envs (SB3's autoreset, terminal observations and time-limit flags are the oracle)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import envfactory  # noqa: F401  (registers the IDs)

pytest.importorskip("stable_baselines3", reason="the [train] extra is not installed (pip install -e '.[train]')")
from stable_baselines3 import SAC, HerReplayBuffer  # noqa: E402
from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor  # noqa: E402

from envfactory.learn.sb3_vector import SB3VectorEnv  # noqa: E402


def _flat(observation, index):
    if isinstance(observation, dict):
        return np.concatenate([np.ravel(observation[key][index]) for key in sorted(observation)])
    return observation[index]


def _single_flat(observation):
    if isinstance(observation, dict):
        return np.concatenate([np.ravel(observation[key]) for key in sorted(observation)])
    return observation


@pytest.mark.parametrize("env_id", ["VX300SPushSim-v0", "UR5ePnPGoalSim-v0"])
def test_the_adapter_steps_as_sb3s_dummy_vec_env_over_single_envs(env_id):
    num_envs, limit = 2, 3
    ours = SB3VectorEnv(gym.make_vec(env_id, num_envs=num_envs, max_episode_steps=limit))
    theirs = DummyVecEnv([lambda: gym.make(env_id, max_episode_steps=limit) for _ in range(num_envs)])
    try:
        ours.seed(4)
        theirs.seed(4)
        first, expected = ours.reset(), theirs.reset()
        for index in range(num_envs):
            np.testing.assert_array_equal(_flat(first, index), _flat(expected, index))
        rng = np.random.default_rng(1)
        space = ours.action_space
        ends = 0
        for step in range(7):
            actions = rng.uniform(space.low, space.high, (num_envs, *space.shape)).astype(np.float32)
            observation, reward, done, info = ours.step(actions)
            expected_observation, expected_reward, expected_done, expected_info = theirs.step(actions)
            np.testing.assert_allclose(reward, expected_reward, rtol=0, atol=1e-6, err_msg=f"step {step}")
            np.testing.assert_array_equal(done, expected_done)
            for index in range(num_envs):
                np.testing.assert_array_equal(_flat(observation, index), _flat(expected_observation, index))
                assert info[index]["TimeLimit.truncated"] == expected_info[index]["TimeLimit.truncated"]
                if done[index]:
                    ends += 1
                    np.testing.assert_array_equal(
                        _single_flat(info[index]["terminal_observation"]),
                        _single_flat(expected_info[index]["terminal_observation"]),
                    )
        assert ends >= num_envs, "no episode ended: the autoreset went untested"
    finally:
        ours.close()
        theirs.close()


def test_sac_with_her_trains_on_the_adapter():
    env = VecMonitor(SB3VectorEnv(gym.make_vec("UR5eReacherGoalSim-v0", num_envs=2, max_episode_steps=5)))
    try:
        model = SAC(
            "MultiInputPolicy",
            env,
            replay_buffer_class=HerReplayBuffer,
            replay_buffer_kwargs={"n_sampled_goal": 2},
            learning_starts=20,
            batch_size=16,
            policy_kwargs={"net_arch": [16, 16]},
            seed=0,
        )
        model.learn(60)
        assert model.num_timesteps >= 60
        assert model.replay_buffer.size() > 0
        assert len(model.ep_info_buffer) >= 4  # VecMonitor saw the 5-step episodes end
    finally:
        env.close()


def test_the_adapter_refuses_what_is_not_the_native_vector_env():
    with pytest.raises(TypeError, match="native vector env"):
        SB3VectorEnv(gym.make_vec("UR5eReacherSim-v0", num_envs=1, vectorization_mode="sync"))
