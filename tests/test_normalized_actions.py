"""normalize_actions=True: Box(-1, 1), zero holds still in delta modes, ±1 reaches the original suite's Min/Max.

The oracle is the original suite's pages' action tables (numbers copied here, not read from the robot YAML)."""

import numpy as np
import pytest

from envfactory.envs.episodes import run_episodes, success_rate
from envfactory.experts import make_policy
from envfactory.views.describe import action_table

# the original suite's pages: Action Space, joint mode (Min, Max per row); delta_coeff 0.05
SEED_JOINT_ROWS = {
    "VX300S": [(-3.14, 3.14), (-1.85, 1.26), (-1.76, 1.61), (-3.14, 3.14), (-1.87, 2.23), (-3.14, 3.14)],
    "UR5e": [(-3.14, 3.14)] * 6,
}
SEED_UR5E_GRIPPER = (0.0, 0.8)  # UR5e PnP action[6], the knuckle, absolute
DELTA_COEFF = 0.05


def _robot(env_id):
    return "VX300S" if env_id.startswith("VX300S") else "UR5e"


def _state_and_command(env, action):
    unwrapped = env.unwrapped
    state = unwrapped.state
    return state, unwrapped.actions.translate(np.asarray(action, np.float32), state)


@pytest.mark.parametrize("env_id", ["VX300SReacherSim-v0", "UR5ePnPSim-v0", "VX300SPushGoalSim-v0"])
def test_space_is_minus_one_to_one_of_the_same_size(env_id, make):
    plain, normalised = make(env_id), make(env_id, normalize_actions=True)
    assert normalised.action_space.shape == plain.action_space.shape
    assert np.all(normalised.action_space.low == -1.0) and np.all(normalised.action_space.high == 1.0)
    observation, _ = normalised.reset(seed=0)
    vector = observation["observation"] if isinstance(observation, dict) else observation
    assert normalised.observation_space.contains(observation)
    # the previous-action columns hold the policy's action, and start at "hold still" (zero in delta mode)
    (slot,) = [slot for slot in normalised.unwrapped.observations.slots if slot.name == "previous_action"]
    arm_rows = 6
    np.testing.assert_array_equal(vector[slot.start : slot.start + arm_rows], 0.0)
    action = normalised.action_space.sample()
    observation, *_ = normalised.step(action)
    vector = observation["observation"] if isinstance(observation, dict) else observation
    np.testing.assert_allclose(vector[slot.start : slot.stop], action, atol=1e-6)


@pytest.mark.parametrize("env_id", ["VX300SReacherSim-v0", "UR5eReacherSim-v0"])
def test_joint_delta_rows_reach_the_seed_min_and_max_and_zero_holds(env_id, make):
    env = make(env_id, normalize_actions=True)
    env.reset(seed=0)
    rows = SEED_JOINT_ROWS[_robot(env_id)]
    for index, (low, high) in enumerate(rows):
        for value, expected in ((1.0, high), (-1.0, low), (0.5, high / 2), (-0.5, low / 2), (0.0, 0.0)):
            action = np.zeros(6)
            action[index] = value
            state, command = _state_and_command(env, action)
            change = command.q_arm - state.q_arm
            wanted = np.zeros(6)
            wanted[index] = DELTA_COEFF * expected
            np.testing.assert_allclose(change, wanted, atol=1e-6, err_msg=f"row {index}, action {value}")
            assert not command.out_of_bounds


def test_zero_means_no_motion_in_the_simulator(make):
    env = make("VX300SReacherSim-v0", normalize_actions=True)
    env.reset(seed=0)
    before = env.unwrapped.state.q_arm.copy()
    for _ in range(5):
        _, _, _, _, info = env.step(np.zeros(6, np.float32))
        assert not info["action_rejected"]
    np.testing.assert_allclose(env.unwrapped.state.q_arm, before, atol=2e-3)
    # and +1 on the shoulder moves it by delta_coeff × the original suite's Max, -1 by × its Min
    for value, seed_bound in ((1.0, 1.26), (-1.0, -1.85)):
        start = env.unwrapped.state.q_arm.copy()
        action = np.zeros(6, np.float32)
        action[1] = value
        _, _, _, _, info = env.step(action)
        assert not info["action_rejected"], info["rejection_reason"]
        assert env.unwrapped.state.q_arm[1] - start[1] == pytest.approx(DELTA_COEFF * seed_bound, abs=5e-3)


def test_pnp_gripper_row_maps_onto_the_seed_range(make):
    env = make("UR5ePnPSim-v0", normalize_actions=True)
    env.reset(seed=0)
    for value, expected in ((-1.0, SEED_UR5E_GRIPPER[0]), (1.0, SEED_UR5E_GRIPPER[1]), (0.0, 0.4)):
        action = np.zeros(7)
        action[6] = value
        _, command = _state_and_command(env, action)
        assert command.gripper == pytest.approx(expected)


def test_absolute_rows_map_affinely(make):
    env = make("VX300SReacherSim-v0", normalize_actions=True, delta_action=False)
    env.reset(seed=0)
    low, high = np.array(SEED_JOINT_ROWS["VX300S"]).T
    for value, expected in ((-1.0, low), (1.0, high), (0.0, (low + high) / 2)):
        _, command = _state_and_command(env, np.full(6, value))
        np.testing.assert_allclose(command.q_arm, expected, atol=1e-6)


def test_outside_minus_one_to_one_is_clipped_and_flagged(make):
    env = make("VX300SReacherSim-v0", normalize_actions=True)
    env.reset(seed=0)
    action = np.zeros(6)
    action[1] = 1.7
    state, command = _state_and_command(env, action)
    assert command.out_of_bounds
    assert command.q_arm[1] - state.q_arm[1] == pytest.approx(DELTA_COEFF * 1.26)


def test_ee_delta_rows_keep_zero_as_hold(make):
    env = make("UR5eReacherSim-v0", normalize_actions=True, ee_action_type=True)
    env.reset(seed=0)
    scale = env.unwrapped.blueprint.action.scale
    np.testing.assert_allclose(scale.to_seed([0.0, 0.0, 0.0]), 0.0)
    np.testing.assert_allclose(scale.to_seed([1.0, -1.0, -1.0]), [1.2, -0.9, -1.5])  # symmetric EE delta rows
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (50, 3))
    np.testing.assert_allclose([scale.to_policy(scale.to_seed(a)) for a in actions], actions, atol=1e-12)


def test_describe_shows_the_mapping(make):
    env = make("VX300SPnPSim-v0", normalize_actions=True)
    text = str([list(column.cells) for column in action_table(env.unwrapped.blueprint).columns])
    assert "-1→-1.85, 0→0, +1→+1.26" in text  # the shoulder, asymmetric
    assert "-1→+0.021, +1→+0.057" in text  # the gripper, affine


@pytest.mark.parametrize("env_id", ["VX300SReacherGoalSim-v0", "UR5ePushSim-v0"])
def test_the_scripted_expert_acts_in_the_normalised_space(env_id, make):
    env = make(env_id, normalize_actions=True)
    results = run_episodes(env, make_policy("scripted", env), episodes=3, seed=10)
    assert success_rate(results) >= 2 / 3
    assert sum(r.rejected for r in results) == 0
