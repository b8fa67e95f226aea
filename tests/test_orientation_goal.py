"""An orientation as part of the goal (task.goal.orientation), on Flip, which turns the cube a quarter about x: the
goal vectors carry a quaternion after the position, and the rewards measure the angle between orientations."""

import gymnasium as gym
import numpy as np
import pybullet as p
import pytest

import envfactory
from envfactory.schema.errors import SpecError

TOLERANCE, TURN_TOLERANCE = 0.04, 0.3  # the UR5e family's, m and rad


def _rodrigues(axis_angle: np.ndarray) -> np.ndarray:
    """The rotation matrix of a rotation vector, by Rodrigues' formula: the oracle's own, not the env's."""
    angle = np.linalg.norm(axis_angle)
    k = axis_angle / angle
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * cross + (1 - np.cos(angle)) * cross @ cross


def _quaternion(axis_angle: np.ndarray) -> np.ndarray:
    angle = np.linalg.norm(axis_angle)
    return np.append(np.sin(angle / 2) * axis_angle / angle, np.cos(angle / 2))


def _place(env, position, quaternion) -> None:
    backend = env.unwrapped.backend
    body = backend.objects["cube"]
    p.resetBasePositionAndOrientation(body, list(position), list(quaternion), physicsClientId=backend.client)
    p.resetBaseVelocity(body, [0, 0, 0], [0, 0, 0], physicsClientId=backend.client)


def _hold(env):
    return env.unwrapped.actions.to_policy(env.unwrapped.actions.hold_action(env.unwrapped.state))


def test_the_goal_vectors_carry_the_cubes_quaternion_after_its_position():
    """achieved_goal is the cube's centre, then its orientation as PyBullet holds it (the UR5e's task frame is the
    world); desired_goal's quaternion is a quarter turn about x, either way, with w >= 0."""
    env = gym.make("UR5eFlipGoalSim-v0")
    try:
        turns = set()
        for seed in range(8):
            observation, _ = env.reset(seed=seed)
            assert env.observation_space.contains(observation)
            backend = env.unwrapped.backend
            position, quaternion = p.getBasePositionAndOrientation(
                backend.objects["cube"], physicsClientId=backend.client
            )
            achieved = observation["achieved_goal"]
            np.testing.assert_allclose(achieved[:3], position, atol=1e-5)
            assert abs(np.dot(achieved[3:], quaternion)) == pytest.approx(1.0, abs=1e-5)  # the same orientation
            desired = observation["desired_goal"][3:]
            assert desired[3] >= 0
            turns.add(tuple(round(float(v), 4) for v in desired))
        half = float(np.round(np.sqrt(0.5), 4))
        assert turns == {(half, 0.0, 0.0, half), (-half, 0.0, 0.0, half)}
    finally:
        env.close()


def test_compute_reward_measures_the_angle_between_orientations_over_a_batch():
    """The oracle: the angle of R1^T R2 from its trace, R built by Rodrigues' formula from the same rotation
    vectors the quaternions come from, the quaternions' signs flipped at random (q and -q are one orientation)."""
    rng = np.random.default_rng(0)
    count = 256
    first, second = rng.normal(0, 1, (count, 3)), rng.normal(0, 1, (count, 3))
    second = first + rng.normal(0, 0.2, (count, 3))  # near and far orientations both
    signs = rng.choice([-1.0, 1.0], (count, 2))
    positions = rng.uniform(-0.1, 0.1, (count, 3))
    offsets = positions + rng.normal(0, 0.03, (count, 3))
    achieved = np.hstack([positions, [_quaternion(v) * s for v, s in zip(first, signs[:, 0])]])
    desired = np.hstack([offsets, [_quaternion(v) * s for v, s in zip(second, signs[:, 1])]])
    angle = np.array(
        [np.arccos(np.clip((np.trace(_rodrigues(a).T @ _rodrigues(b)) - 1) / 2, -1, 1)) for a, b in zip(first, second)]
    )
    distance = np.linalg.norm(positions - offsets, axis=1)
    both = (distance < TOLERANCE) & (angle < TURN_TOLERANCE)
    assert both.any() and ((distance < TOLERANCE) & ~both).any()  # the angle alone decides some rows
    for reward_type, expected in (
        ("Sparse", both - 1.0),
        ("Dense", -2.0 * distance - 0.5 * angle + 20.0 * both - 0.5),  # the task's weights; nothing grasped
    ):
        env = gym.make("UR5eFlipGoalSim-v0", reward_type=reward_type)
        try:
            _, info = env.reset(seed=0)
            rewards = env.unwrapped.compute_reward(achieved, desired, np.array([info] * count))
            np.testing.assert_allclose(rewards, expected, atol=1e-6, err_msg=reward_type)
        finally:
            env.close()


def test_success_needs_the_turn_as_well_as_the_place():
    env = gym.make("UR5eFlipGoalSim-v0")
    try:
        observation, _ = env.reset(seed=3)
        goal = observation["desired_goal"]
        _place(env, goal[:3], [0, 0, 0, 1])  # at the goal, upright
        _, reward, _, _, info = env.step(_hold(env))
        assert (reward, info["is_success"]) == (-1.0, False) and info["angle"] == pytest.approx(np.pi / 2, abs=0.02)
        _place(env, goal[:3], goal[3:])  # at the goal, turned: resting on a side face, the centre as high
        _, reward, terminated, _, info = env.step(_hold(env))
        assert (reward, terminated, info["is_success"]) == (0.0, True, True) and info["angle"] < 0.02
    finally:
        env.close()


def test_the_observation_holds_the_turn_still_to_make():
    """goal_rotation is the rotation vector that turns the upright cube into its goal: a quarter about x."""
    env = gym.make("UR5eFlipSim-v0")
    try:
        observation, _ = env.reset(seed=1)
        slots = {s.term.name: s for s in env.unwrapped.blueprint.policy_observation}
        rotation, angle = slots["goal_rotation"], slots["goal_angle"]
        turn = observation[rotation.start : rotation.stop]
        assert abs(turn[0]) == pytest.approx(np.pi / 2, abs=1e-4) and np.allclose(turn[1:], 0.0, atol=1e-4)
        assert observation[angle.start] == pytest.approx(np.pi / 2, abs=1e-4)
    finally:
        env.close()


@pytest.mark.parametrize(
    "override, message",
    [
        ("+task.goal.orientation.ee={tolerance: 0.3}", "task.goal.orientation.ee: orientation goals are objects'"),
        ("+task.goal.lift={height: 0.1}", "task.goal.lift: the lift stage's goal is a point"),
        (
            "+task.reward.dense.angle.params={object: cub}",
            "object 'cub' has no orientation goal; the orientation goal's parts: cube",
        ),
    ],
)
def test_orientation_mistakes_are_named(override, message):
    with pytest.raises(SpecError, match=message):
        envfactory.blueprint("UR5eFlipSim-v0", [override])


def test_an_angle_term_without_an_orientation_goal_is_named():
    with pytest.raises(SpecError, match="goal_angle.*the goal holds no orientation: declare task.goal.orientation"):
        envfactory.blueprint("UR5ePushSim-v0", ["+task.reward.dense.angle={term: goal_angle, weight: -1.0}"])
