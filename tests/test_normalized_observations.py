"""`normalize_observations=True`: the same episode, every column mapped by its declared bounds, the goals by
the goal box, and rewards still the original suite's formula in metres."""

import numpy as np
import pytest

KWARGS = {"ee_action_type": True, "normalize_actions": True}


def _twin_episodes(make, env_id, steps=30):
    raw, scaled = make(env_id, **KWARGS), make(env_id, normalize_observations=True, **KWARGS)
    raw_obs, _ = raw.reset(seed=4)
    scaled_obs, _ = scaled.reset(seed=4)
    raw.action_space.seed(4)
    pairs = [(raw_obs, scaled_obs, None)]
    for _ in range(steps):
        action = raw.action_space.sample()
        raw_obs, _, _, _, _ = raw.step(action)
        scaled_obs, _, _, _, info = scaled.step(action)
        pairs.append((raw_obs, scaled_obs, info))
    return raw, scaled, pairs


# Slide's goals lie on the table top: a goal box flat in z
@pytest.mark.parametrize("env_id", ["UR5eReacherGoalSim-v0", "VX300SPushGoalSim-v0", "VX300SSlideGoalSim-v0"])
def test_goal_env_columns_and_goals_are_mapped_by_their_declared_boxes(make, env_id):
    raw, scaled, pairs = _twin_episodes(make, env_id)
    box = raw.observation_space["observation"]
    goal_low, goal_high = raw.observation_space["desired_goal"].low, raw.observation_space["desired_goal"].high
    for raw_obs, scaled_obs, _ in pairs:
        assert scaled.observation_space.contains(scaled_obs)
        expected = (raw_obs["observation"] - (box.low + box.high) / 2) / ((box.high - box.low) / 2)
        np.testing.assert_allclose(scaled_obs["observation"], expected, atol=1e-5)
        for key in ("achieved_goal", "desired_goal"):
            half = (goal_high - goal_low) / 2
            expected = (raw_obs[key] - (goal_low + goal_high) / 2) / np.where(half > 0, half, 1.0)  # flat: unit kept
            np.testing.assert_allclose(scaled_obs[key], expected, atol=1e-5)
    assert np.all(np.abs(np.stack([s["observation"] for _, s, _ in pairs])) <= 1.0 + 1e-6)


@pytest.mark.parametrize("env_id", ["UR5eReacherGoalSim-v0", "VX300SPushGoalSim-v0"])
def test_rewards_on_scaled_goals_are_the_seed_formula_in_metres(make, env_id):
    raw, scaled, pairs = _twin_episodes(make, env_id)
    tolerance = scaled.unwrapped.blueprint.spec.task.goal.tolerance
    # HER's relabelling: every goal seen (achieved and desired) against every other, in one batch
    goals = np.stack([r[key] for r, _, _ in pairs for key in ("achieved_goal", "desired_goal")])
    scaled_goals = np.stack([s[key] for _, s, _ in pairs for key in ("achieved_goal", "desired_goal")])
    first, second = np.meshgrid(np.arange(len(goals)), np.arange(len(goals)))
    first, second = first.ravel(), second.ravel()
    infos = [pairs[-1][2]] * len(first)
    distance = np.linalg.norm(goals[first] - goals[second], axis=-1)
    expected = np.where(distance < tolerance, 0.0, -1.0)
    got = scaled.unwrapped.compute_reward(scaled_goals[first], scaled_goals[second], infos)
    near = np.abs(distance - tolerance) < 1e-5  # float32 rounding of the scaled goals at the threshold
    np.testing.assert_array_equal(got[~near], expected[~near])
    assert (expected == 0).sum() > len(pairs) and (expected == -1).any()  # both outcomes are tried


def test_standard_env_vector_is_scaled_too(make):
    raw, scaled, pairs = _twin_episodes(make, "VX300SReacherSim-v0", steps=10)
    box = raw.observation_space
    assert scaled.observation_space == type(box)(-1.0, 1.0, box.shape, np.float32)
    for raw_obs, scaled_obs, _ in pairs:
        np.testing.assert_allclose(
            scaled_obs, (raw_obs - (box.low + box.high) / 2) / ((box.high - box.low) / 2), atol=1e-5
        )
