"""Flip: the cube turned a quarter about x and set down at the goal; its orientation is part of the goal."""

import gymnasium as gym
import numpy as np
import pytest
from expert_runs import full_episodes

from envfactory.envs.episodes import run_episodes, success_rate
from envfactory.experts import make_policy

FLIP_IDS = ["PandaFlipSim-v0", "UR5eFlipSim-v0", "VX300SFlipSim-v0", "NED2FlipSim-v0"]


def test_the_goal_asks_for_a_side_face_down_and_the_cube_rests_on_it():
    """Run to its time limit, the expert's episode ends with the cube resting where the goal is, its top face
    turned to the side the goal's quaternion says: the cube's own z axis (read from PyBullet's pose, the oracle)
    lies along -+y, as a quarter turn about +-x puts it, and the cube is at rest."""
    import pybullet as p

    env = gym.make("UR5eFlipSim-v0")
    try:
        results = run_episodes(env, make_policy("scripted", env), episodes=2, seed=0, stop_on_success=False)
        assert all(r.success for r in results), [(r.seed, r.length) for r in results]
        unwrapped = env.unwrapped
        backend = unwrapped.backend
        _, quaternion = p.getBasePositionAndOrientation(backend.objects["cube"], physicsClientId=backend.client)
        up = np.array(p.getMatrixFromQuaternion(quaternion)).reshape(3, 3)[:, 2]  # the cube's own z, world frame
        turn = unwrapped.goal[3:]  # (x, 0, 0, w): a quarter about +x turns z to -y, about -x to +y
        np.testing.assert_allclose(up, [0.0, -np.sign(turn[0]), 0.0], atol=0.05)
        assert np.linalg.norm(unwrapped.state.objects["cube"].linear_velocity) < 1e-3
    finally:
        env.close()


def test_the_expert_flips():
    """A quick sample in the default run (the 20-seed figures are the slow test below)."""
    results = full_episodes("VX300SFlipSim-v0", episodes=3)
    assert success_rate(results) >= 2 / 3, [(r.seed, r.length, r.success) for r in results]
    assert sum(r.rejected for r in results) == 0  # the expert never asks for an unsafe motion


@pytest.mark.slow
@pytest.mark.parametrize("env_id", FLIP_IDS)
def test_the_expert_flips_over_20_seeds(env_id):
    results = full_episodes(env_id, episodes=20)
    assert success_rate(results) >= 0.8, [(r.seed, r.length) for r in results if not r.success]


def test_ee_mode_is_refused_for_a_goal_that_turns_the_cube():
    """EE mode holds the gripper pointing down: an env whose goal asks for a turn could never be solved in it."""
    import envfactory

    with pytest.raises(envfactory.SpecError, match="gym.make kwarg ee_action_type=True: env.action.ee: the goal turns"):
        gym.make("PandaFlipSim-v0", ee_action_type=True)
