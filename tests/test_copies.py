"""Envs survive pickle and deepcopy: a copy is a fresh env of the same blueprint with the same random state."""

import copy
import pickle

import numpy as np
import pytest

from envfactory.factory import blueprint

COPIES = {"pickle": lambda env: pickle.loads(pickle.dumps(env)), "deepcopy": copy.deepcopy}


def _vector(observation):
    return observation["observation"] if isinstance(observation, dict) else observation


@pytest.mark.parametrize("how", sorted(COPIES))
@pytest.mark.parametrize("env_id", ["UR5eReacherSim-v0", "VX300SPnPGoalSim-v0"])
def test_a_copy_is_a_fresh_env_of_the_same_blueprint(make, env_id, how):
    env = make(env_id, overrides=["env.timing.action_cycle_time=0.1"])
    env.reset(seed=7)
    env.step(env.action_space.sample())  # mid-episode: the copy must not depend on it
    duplicate = COPIES[how](env)
    try:
        assert duplicate.unwrapped is not env.unwrapped
        assert duplicate.unwrapped.backend is not env.unwrapped.backend
        assert duplicate.unwrapped.blueprint.to_json() == env.unwrapped.blueprint.to_json()
        assert duplicate.observation_space == env.observation_space
        assert duplicate.action_space == env.action_space
        with pytest.raises(RuntimeError, match="reset"):  # a copy starts un-reset: no physics state is copied
            duplicate.unwrapped.step(duplicate.action_space.sample())
        # the random generator's state travels: both envs' next unseeded reset samples the same goal
        observation, _ = duplicate.reset()
        original, _ = env.reset()
        np.testing.assert_allclose(duplicate.unwrapped.goal, env.unwrapped.goal)
        np.testing.assert_allclose(_vector(observation), _vector(original), atol=1e-6)
        action = env.action_space.sample()
        after_copy, _, _, _, info_copy = duplicate.step(action)
        after, _, _, _, info = env.step(action)
        assert info_copy["action_rejected"] == info["action_rejected"]
        assert duplicate.observation_space.contains(after_copy)
    finally:
        duplicate.close()


def test_a_blueprint_pickles_with_its_terms_by_name():
    compiled = blueprint("UR5ePnPGoalSim-v0")
    restored = pickle.loads(pickle.dumps(compiled))
    assert restored.to_json() == compiled.to_json()
    for mine, theirs in zip(restored.observation, compiled.observation, strict=True):
        assert mine.term is theirs.term  # the registry's own term object, callables and all
    for mine, theirs in zip(restored.rewards, compiled.rewards, strict=True):
        assert mine.term is theirs.term
