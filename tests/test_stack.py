"""Stack: two cubes with a goal each, the upper one on top of the lower; success needs both."""

import gymnasium as gym
import mujoco
import numpy as np
import pybullet as p
import pytest
from expert_runs import full_episodes

from envfactory.envs.episodes import success_rate

STACK_IDS = ["PandaStackSim-v0", "UR5eStackSim-v0", "VX300SStackSim-v0", "RX200StackSim-v0", "NED2StackSim-v0"]
EDGE = 0.04  # the cubes' edge, and the upper goal's height over the lower one's
TOLERANCE = 0.02  # the UR5e family's


def _engine_position(env, name: str) -> np.ndarray:
    """The cube's centre as the engine itself holds it (world frame), not through the env's readings."""
    backend = env.unwrapped.backend
    if env.unwrapped.blueprint.backend == "pybullet":
        return np.array(p.getBasePositionAndOrientation(backend.objects[name], physicsClientId=backend.client)[0])
    body = mujoco.mj_name2id(backend.model, mujoco.mjtObj.mjOBJ_BODY, f"object:{name}")
    return backend.data.xpos[body].copy()


def _place(env, name: str, task_position) -> None:
    """Put a cube at a point of the task frame, at rest and square, directly in the engine."""
    unwrapped = env.unwrapped
    backend, world = unwrapped.backend, unwrapped.task_frame.to_world(np.asarray(task_position, float))
    if unwrapped.blueprint.backend == "pybullet":
        body = backend.objects[name]
        p.resetBasePositionAndOrientation(body, world.tolist(), [0, 0, 0, 1], physicsClientId=backend.client)
        p.resetBaseVelocity(body, [0, 0, 0], [0, 0, 0], physicsClientId=backend.client)
        return
    body = mujoco.mj_name2id(backend.model, mujoco.mjtObj.mjOBJ_BODY, f"object:{name}")
    joint = backend.model.body_jntadr[body]
    address, velocity = backend.model.jnt_qposadr[joint], backend.model.jnt_dofadr[joint]
    backend.data.qpos[address : address + 7] = [*world, 1, 0, 0, 0]
    backend.data.qvel[velocity : velocity + 6] = 0
    mujoco.mj_forward(backend.model, backend.data)


def _hold(env) -> np.ndarray:
    return env.unwrapped.actions.to_policy(env.unwrapped.actions.hold_action(env.unwrapped.state))


def test_the_goal_vectors_hold_both_cubes_in_turn():
    """achieved_goal is the lower cube's centre, then the upper's, as PyBullet holds them; desired_goal is the
    sampled goal, then the same goal one edge higher."""
    env = gym.make("UR5eStackGoalSim-v0")
    try:
        for seed in range(3):
            observation, _ = env.reset(seed=seed)
            frame = env.unwrapped.task_frame
            engine = np.concatenate([frame.to_task(_engine_position(env, name)) for name in ("lower", "upper")])
            np.testing.assert_allclose(observation["achieved_goal"], engine, atol=1e-5)
            desired = observation["desired_goal"]
            assert desired.shape == (6,) and env.observation_space["desired_goal"].contains(desired)
            np.testing.assert_allclose(desired[3:], desired[:3] + [0.0, 0.0, EDGE], atol=1e-6)
    finally:
        env.close()


@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_success_needs_the_upper_cube_on_top_and_it_stays_there(engine):
    """The lower cube at its goal with the upper one beside it on the table is no success (its goal is one edge
    up, beyond the tolerance); on top it is, and the cube-on-cube contact holds it there for 3 s in both
    engines."""
    env = gym.make("UR5eStackGoalSim-v0", engine=engine)
    try:
        env.reset(seed=0)
        goal = env.unwrapped.goal[:3]
        _place(env, "lower", goal)
        _place(env, "upper", goal + [0.0, 0.08, 0.0])
        _, reward, terminated, _, info = env.step(_hold(env))
        assert (reward, terminated, info["is_success"]) == (-1.0, False, False)
        _place(env, "upper", goal + [0.0, 0.0, EDGE])
        _, reward, terminated, _, info = env.step(_hold(env))
        assert (reward, terminated, info["is_success"]) == (0.0, True, True)
        for _ in range(6):
            env.unwrapped.backend.advance(0.5)
        lower, upper = (_engine_position(env, name) for name in ("lower", "upper"))
        np.testing.assert_allclose(upper - lower, [0.0, 0.0, EDGE], atol=2e-3)
    finally:
        env.close()


def test_compute_reward_measures_each_cube_on_its_own_over_a_batch():
    """HER relabels a batch. Sparse: 0 only with both cubes within tolerance of their own goals. Dense: -2 times
    the sum of both distances, 5 for the lower cube placed, 20 for both, -0.5 a step (the task's weights)."""
    rng = np.random.default_rng(0)
    achieved = rng.uniform(-0.1, 0.1, (256, 6))
    desired = achieved + rng.normal(0, 0.015, (256, 6))
    lower = np.linalg.norm(achieved[:, :3] - desired[:, :3], axis=1)
    upper = np.linalg.norm(achieved[:, 3:] - desired[:, 3:], axis=1)
    both = (lower < TOLERANCE) & (upper < TOLERANCE)
    assert both.any() and (~both).any() and ((lower < TOLERANCE) & ~both).any()  # every case is tried
    for reward_type, expected in (
        ("Sparse", both.astype(float) - 1.0),
        ("Dense", -2.0 * (lower + upper) + 5.0 * (lower < TOLERANCE) + 20.0 * both - 0.5),
    ):
        env = gym.make("UR5eStackGoalSim-v0", reward_type=reward_type)
        try:
            _, info = env.reset(seed=0)
            rewards = env.unwrapped.compute_reward(achieved, desired, np.array([info] * len(achieved)))
            np.testing.assert_allclose(rewards, expected, atol=1e-9, err_msg=reward_type)
            one = env.unwrapped.compute_reward(achieved[0], desired[0], info)
            assert one == pytest.approx(expected[0])
        finally:
            env.close()


def test_each_cube_is_pointed_at_its_own_goal():
    env = gym.make("UR5eStackSim-v0")
    try:
        observation, _ = env.reset(seed=1)
        state, goal = env.unwrapped.state, env.unwrapped.goal
        slots = {
            (s.term.name, s.bound.from_): s for s in env.unwrapped.blueprint.policy_observation if s.goal_dependent
        }
        for name, own in (("lower", goal[:3]), ("upper", goal[3:])):
            offset = own - state.objects[name].position
            direction, distance = slots["goal_direction", name], slots["goal_distance", name]
            np.testing.assert_allclose(
                observation[direction.start : direction.stop], offset / np.linalg.norm(offset), atol=1e-5
            )
            assert observation[distance.start] == pytest.approx(np.linalg.norm(offset), abs=1e-5)
    finally:
        env.close()


def test_the_expert_stacks():
    """A quick sample in the default run (the 20-seed figures are the slow test below). Each episode runs to its
    time limit and counts its last step: the expert lets go of the upper cube, so a success is a stack that
    stands on its own, not one the hand still holds together."""
    results = full_episodes("UR5eStackSim-v0", episodes=3)
    assert success_rate(results) >= 2 / 3, [(r.seed, r.length, r.success) for r in results]
    assert sum(r.rejected for r in results) == 0  # the expert never asks for an unsafe motion


@pytest.mark.slow
@pytest.mark.parametrize("env_id", STACK_IDS)
def test_the_expert_stacks_over_20_seeds(env_id):
    results = full_episodes(env_id, episodes=20)
    assert success_rate(results) >= 0.8, [(r.seed, r.length) for r in results if not r.success]
