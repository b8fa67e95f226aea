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


# ---------------------------------------------------------------- the native vector env (vector_entry_point)


def _one_sim_id_per_family() -> list[str]:
    chosen: dict[str, str] = {}
    for env_id, record in sorted(envfactory.records().items()):
        if record.backend == "sim" and not record.goal_env and record.source == "built-in":
            chosen.setdefault(str(record.family.path), env_id)
    return sorted(chosen.values())


FAMILY_SIM_IDS = _one_sim_id_per_family()


def _actions(space, count: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [rng.uniform(space.low, space.high).astype(space.dtype) for _ in range(count)]


def _rows(observation, index=None):
    """An observation as a flat tuple of arrays (a Dict's keys in order), of one env of a batch if `index`."""
    parts = [observation[key] for key in sorted(observation)] if isinstance(observation, dict) else [observation]
    return [part if index is None else part[index] for part in parts]


def _same_episodes_as_single_envs(env_id: str, num_envs: int = 2, steps: int = 7, limit: int = 3, **kwargs):
    """The oracle: `num_envs` envs from gym.make, seeded as gymnasium seeds a vector env's (seed + i), reset by
    hand the step after their episode ends (gymnasium's next-step autoreset: reward 0, not done)."""
    vector = gym.make_vec(env_id, num_envs=num_envs, max_episode_steps=limit, **kwargs)
    singles = [gym.make(env_id, max_episode_steps=limit, **kwargs) for _ in range(num_envs)]
    try:
        assert type(vector.unwrapped).__name__ == "RobotVectorEnv"
        observations, _ = vector.reset(seed=11)
        expected = [single.reset(seed=11 + index)[0] for index, single in enumerate(singles)]
        for index in range(num_envs):
            for ours, theirs in zip(_rows(observations, index), _rows(expected[index]), strict=True):
                np.testing.assert_array_equal(ours, theirs, err_msg=f"{env_id}: env {index} at reset")
        ended = [False] * num_envs
        per_env = [_actions(singles[0].action_space, steps, seed=index) for index in range(num_envs)]
        for step in range(steps):
            batch = np.stack([per_env[index][step] for index in range(num_envs)])
            observations, rewards, terminated, truncated, _ = vector.step(batch)
            for index, single in enumerate(singles):
                if ended[index]:
                    expected_obs, _ = single.reset()
                    expected_step = (0.0, False, False)
                else:
                    expected_obs, reward, done, cut, _ = single.step(per_env[index][step])
                    expected_step = (reward, done, cut)
                ended[index] = expected_step[1] or expected_step[2]
                where = f"{env_id}: env {index}, step {step}"
                assert (rewards[index], terminated[index], truncated[index]) == expected_step, where
                for ours, theirs in zip(_rows(observations, index), _rows(expected_obs), strict=True):
                    np.testing.assert_array_equal(ours, theirs, err_msg=where)
        assert any(truncated) or any(ended), f"{env_id}: no episode ended within {steps} steps: autoreset untested"
    finally:
        vector.close()
        for single in singles:
            single.close()


@pytest.mark.parametrize("env_id", FAMILY_SIM_IDS)
def test_native_vector_env_episodes_equal_single_env_episodes(env_id):
    _same_episodes_as_single_envs(env_id)


@pytest.mark.parametrize("env_id", ["UR5ePushGoalSim-v0", "VX300SDrawerSim-v0"])
def test_native_vector_env_on_mujoco_shares_one_model_and_equals_single_envs(env_id):
    _same_episodes_as_single_envs(env_id, num_envs=3, engine="mujoco")
    vector = gym.make_vec(env_id, num_envs=3, engine="mujoco")
    try:
        models = {id(env.backend.model) for env in vector.unwrapped.envs}
        datas = {id(env.backend.data) for env in vector.unwrapped.envs}
        assert len(models) == 1 and len(datas) == 3
        checks = {id(env.safety) for env in vector.unwrapped.envs}
        assert len(checks) == 3, "each env keeps its own safety check"
        assert len({id(env.blueprint) for env in vector.unwrapped.envs}) == 1, "one compiled blueprint"
    finally:
        vector.close()


def test_randomized_mujoco_envs_each_build_their_own_model():
    vector = gym.make_vec("UR5ePushSim-v0", num_envs=2, engine="mujoco", randomize=True)
    try:
        envs = vector.unwrapped.envs
        assert envs[0].backend.model is not envs[1].backend.model
        vector.reset(seed=3)
        masses = [env.backend.model.body_mass.copy() for env in envs]
        assert not np.array_equal(*masses), "two randomized envs drew the same masses: they share a model"
    finally:
        vector.close()


def test_same_step_autoreset_reports_the_final_observation():
    vector = gym.make_vec("UR5eReacherSim-v0", num_envs=2, max_episode_steps=2, autoreset_mode="SameStep")
    single = gym.make("UR5eReacherSim-v0", max_episode_steps=2)
    try:
        first, _ = vector.reset(seed=0)
        single.reset(seed=0)
        hold = np.zeros(vector.action_space.shape, dtype=np.float32)
        vector.step(hold)
        single.step(hold[0])
        observations, _, _, truncated, infos = vector.step(hold)
        final, *_ = single.step(hold[0])
        assert truncated.all()
        np.testing.assert_array_equal(infos["final_obs"][0], final)
        assert infos["_final_obs"].all()
        restarted, _ = single.reset()
        np.testing.assert_array_equal(observations[0], restarted)  # the new episode's first observation
    finally:
        vector.close()
        single.close()


def test_disabled_autoreset_refuses_a_step_of_an_ended_env_until_its_reset():
    vector = gym.make_vec("UR5eReacherSim-v0", num_envs=2, max_episode_steps=1, autoreset_mode="Disabled")
    try:
        vector.reset(seed=0)
        hold = np.zeros(vector.action_space.shape, dtype=np.float32)
        _, _, _, truncated, _ = vector.step(hold)
        assert truncated.all()
        with pytest.raises(RuntimeError, match="autoreset is disabled"):
            vector.step(hold)
        vector.reset(options={"reset_mask": np.array([True, True])})
        vector.step(hold)
    finally:
        vector.close()


def test_vector_env_refuses_wrong_seeds_and_masks():
    vector = gym.make_vec("UR5eReacherSim-v0", num_envs=2)
    try:
        with pytest.raises(ValueError, match="3 seeds for 2 envs"):
            vector.reset(seed=[1, 2, 3])
        with pytest.raises(ValueError, match="reset_mask"):
            vector.reset(options={"reset_mask": np.array([1, 0])})
    finally:
        vector.close()


def test_a_vector_env_of_several_envs_on_a_real_robot_is_refused_before_anything_connects():
    with pytest.raises(ValueError, match="would send 2 envs' commands to one robot"):
        gym.make_vec("UR5eReacherReal-v0", num_envs=2)
