import gymnasium as gym
import numpy as np
import pytest
from conftest import SIM_IDS
from gymnasium.utils.env_checker import check_env


@pytest.mark.parametrize("env_id", SIM_IDS)
def test_check_env(env_id):
    env = gym.make(env_id)
    try:
        check_env(env.unwrapped, skip_render_check=True)
    finally:
        env.close()


@pytest.mark.parametrize("env_id", ["UR5eReacherSim-v0", "VX300SReacherGoalSim-v0"])
def test_same_seed_same_trajectory(env_id, make):
    def rollout():
        env = make(env_id)
        env.action_space.seed(7)
        first, _ = env.reset(seed=123)
        trace = [first]
        for _ in range(8):
            observation, reward, *_ = env.step(env.action_space.sample())
            trace.append((observation, reward))
        return trace

    a, b = rollout(), rollout()
    assert repr(a) == repr(b)


def test_seed_kwarg_seeds_the_first_reset(make):
    goals = [make("UR5eReacherSim-v0", seed=5).unwrapped for _ in range(2)]
    for env in goals:
        env.reset()
    assert np.array_equal(goals[0].goal, goals[1].goal)
    assert np.all(goals[0].goal >= [0.40, -0.30, 0.85]) and np.all(goals[0].goal <= [0.80, 0.30, 1.10])


def test_nan_action_is_rejected_and_never_moves_the_arm(make):
    env = make("UR5eReacherSim-v0")
    env.reset(seed=0)
    before = env.unwrapped.state.q_arm.copy()
    _, reward, _, _, info = env.unwrapped.step(np.array([np.nan, 0, 0, 0, 0, np.inf], dtype=np.float32))
    assert info["action_rejected"] == 1.0 and "non-finite" in info["rejection_reason"]
    np.testing.assert_allclose(env.unwrapped.state.q_arm, before, atol=2e-3)
    assert np.all(np.isfinite(env.unwrapped.state.previous_action))


def test_unsafe_absolute_target_is_rejected_with_penalty(make):
    # Elbow folded down hard at the home pose drives the wrist into the table.
    env = make("UR5eReacherSim-v0", delta_action=False, max_joint_delta=3.2)
    env.reset(seed=0)
    home = env.unwrapped.state.q_arm.copy()
    target = home.copy()
    target[1] = 0.6  # shoulder lift swings the upper arm down past horizontal
    _, reward, _, _, info = env.step(target.astype(np.float32))
    assert info["action_rejected"] == 1.0, info
    assert "link" in info["rejection_reason"]
    np.testing.assert_allclose(env.unwrapped.state.q_arm, home, atol=2e-3)
    dense_without_penalty = reward + 5.0
    assert dense_without_penalty < 0  # the -5 none_exe penalty was part of the reward


def test_joint_bound_is_clipped_and_penalised(make):
    env = make("VX300SReacherSim-v0")
    env.reset(seed=0)
    for _ in range(30):  # push the shoulder against its upper bound of 1.26 rad
        _, _, _, _, info = env.step(np.array([0, 3.14, 0, 0, 0, 0], dtype=np.float32))
        if info["action_out_of_bounds"]:
            break
    assert info["action_out_of_bounds"] == 1.0
    assert env.unwrapped.state.q_arm[1] <= 1.26 + 1e-3


def test_goal_env_compute_reward_matches_step_rewards(make):
    env = make("UR5eReacherGoalSim-v0", reward_type="Dense")
    observation, _ = env.reset(seed=3)
    achieved, desired, infos, rewards = [], [], [], []
    for _ in range(12):
        observation, reward, _, _, info = env.step(env.action_space.sample())
        achieved.append(observation["achieved_goal"])
        desired.append(observation["desired_goal"])
        infos.append(info)
        rewards.append(reward)
    batch = env.unwrapped.compute_reward(np.array(achieved), np.array(desired), np.array(infos))
    np.testing.assert_allclose(batch, rewards, rtol=1e-5, atol=1e-5)
    # relabelling with the achieved goal as the desired goal gives the reached bonus
    relabelled = env.unwrapped.compute_reward(np.array(achieved), np.array(achieved), np.array(infos))
    assert np.all(relabelled > np.array(rewards))


def test_sparse_terminates_at_goal_and_dense_does_not(make):
    for reward_type, expect_termination in (("Sparse", True), ("Dense", False)):
        env = make("UR5eReacherGoalSim-v0", reward_type=reward_type).unwrapped
        goal = np.array([[0.6, 0.0, 0.9]])
        _, info = env.reset(seed=0)  # a step's info: every key the terms read, flags at 0
        assert env.compute_terminated(goal, goal, [info])[0] == expect_termination
        assert env.compute_reward(goal, goal + [0, 0, 0.5], [info])[0] == pytest.approx(
            -1.0 if reward_type == "Sparse" else -1.5
        )


def test_missing_step_info_is_an_error_not_a_silent_zero(make):
    env = make("UR5eReacherGoalSim-v0", reward_type="Dense").unwrapped
    goal = np.array([[0.6, 0.0, 0.9]])
    with pytest.raises(KeyError, match="step info lacks 'action_out_of_bounds'"):
        env.compute_reward(goal, goal, [{}])


def test_rgb_render_headless(make):
    env = make("VX300SReacherSim-v0", render_mode="rgb_array")
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (360, 480, 3) and frame.dtype == np.uint8
    assert frame.std() > 5  # a scene, not a blank image


def test_each_step_simulates_action_cycle_time(make):
    env = make("UR5eReacherSim-v0", action_cycle_time=0.25)
    env.reset(seed=0)
    backend = env.unwrapped.backend
    env.step(np.zeros(6, dtype=np.float32))
    assert backend._sim_time == pytest.approx(0.25, abs=backend.dt)


def test_realtime_mode_paces_by_wall_clock(make):
    import time

    env = make("VX300SReacherSim-v0", realtime_mode=True, action_cycle_time=0.2, environment_loop_rate=10.0)
    env.reset(seed=0)
    start = time.perf_counter()
    env.step(np.zeros(6, dtype=np.float32))
    env.step(np.zeros(6, dtype=np.float32))
    assert time.perf_counter() - start >= 0.4
