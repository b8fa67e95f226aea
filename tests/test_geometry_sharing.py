"""A robot's geometry is built once per process and shared by every env; each env measures with its own copy,
so envs stepped in turn behave exactly as envs stepped alone."""

from __future__ import annotations

import json
import subprocess
import sys

import gymnasium as gym
import numpy as np

import envfactory  # noqa: F401  (registers the IDs)
from envfactory.geometry import robot_model

COUNT_BUILDS = """
import json, gymnasium as gym, envfactory
from envfactory.geometry import robot_model
envs = [gym.make(env_id) for env_id in {ids!r}]
print(json.dumps(dict(robot_model.builds)))
"""


def _builds_in_fresh_process(ids: list[str]) -> dict:
    out = subprocess.run(
        [sys.executable, "-c", COUNT_BUILDS.format(ids=ids)], capture_output=True, text=True, check=True, timeout=300
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_one_robot_is_built_once_whatever_its_ids():
    ids = ["UR5eReacherSim-v0", "UR5eReacherSim-v0", "UR5eReacherGoalSim-v0", "UR5ePushSim-v0", "UR5ePnPSim-v0"]
    assert _builds_in_fresh_process(ids) == {"kinematics": 1, "collision": 1}


def test_each_robot_is_built_once():
    ids = ["VX300SReacherSim-v0", "UR5eReacherSim-v0", "VX300SPushSim-v0", "UR5eReacherGoalSim-v0"]
    assert _builds_in_fresh_process(ids) == {"kinematics": 2, "collision": 2}


def test_envs_share_the_structure_and_own_the_measuring_state():
    first, second = gym.make("VX300SPushSim-v0").unwrapped, gym.make("VX300SPushSim-v0").unwrapped
    one, other = first.safety.collision, second.safety.collision
    assert one.geometry is other.geometry and one.lever is other.lever  # built once
    assert one.data is not other.data and one._frames is not other._frames  # measured apart
    assert one.kinematics.data is not other.kinematics.data
    assert one.gripper_sweep.collision is one and other.gripper_sweep.collision is other
    first.close(), second.close()


def _rollout(envs, seed: int, steps: int) -> list[list[np.ndarray]]:
    """Step the envs in turn with the same random actions; each env's observations."""
    rng = np.random.default_rng(seed)
    seen = [[env.reset(seed=seed)[0]] for env in envs]
    for _ in range(steps):
        action = rng.uniform(envs[0].action_space.low, envs[0].action_space.high).astype(np.float32)
        for index, env in enumerate(envs):
            seen[index].append(env.step(action)[0])
    return seen


def test_envs_stepped_in_turn_match_an_env_stepped_alone():
    env_id = "VX300SPushSim-v0"
    alone = _rollout([gym.make(env_id)], seed=3, steps=15)[0]
    interleaved = _rollout([gym.make(env_id), gym.make(env_id)], seed=3, steps=15)
    for observations in interleaved:
        np.testing.assert_array_equal(np.array(observations), np.array(alone))


def test_the_counter_counts():
    """The build counter moves when a geometry is built: a safety setting never used before builds anew."""
    before = robot_model.builds["collision"]
    env = gym.make("VX300SReacherSim-v0", overrides=["env.safety.surface_margin=0.0171"])
    assert robot_model.builds["collision"] == before + 1
    env.close()
