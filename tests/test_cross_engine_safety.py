"""Where accepted steps leave the simulated links, judged by the engine that did not run them (MuJoCo for PyBullet's
steps, PyBullet for MuJoCo's), neither of them the safety check's own geometry: no link ends inside the margin.
devkit/bench/safety_cross_engine.py runs the same on every Sim ID; this is its UR5e share, whose heavy joints left
PyBullet's commanded line (tests/test_synchronous_motion.py: 0.17 rad) before its motors were given the line
substep by substep."""

from __future__ import annotations

import numpy as np
import pytest

import envfactory
from devkit.oracles.bullet_judge import BulletJudge
from devkit.oracles.cross_engine import MujocoJudge, judge_end_poses, simulated_joints
from envfactory.envs import RobotEnv


def _pose_above_table(env, height: float) -> np.ndarray:
    """The home pose with the shoulder lowered until the check's model puts the lowest link `height` above the
    table (bisection on the shoulder lift)."""
    home = np.asarray(env.home, float)
    gripper = env.state.gripper

    def lowest(lift: float) -> float:
        q = home.copy()
        q[1] += lift
        return float(np.min(env.safety.clearances(q, gripper)[: len(env.safety.collision.scene_shape)]))

    low, high = 0.0, 1.5
    for _ in range(40):
        middle = (low + high) / 2
        low, high = (middle, high) if lowest(middle) > height else (low, middle)
    q = home.copy()
    q[1] += low
    return q


@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_both_judges_see_a_link_placed_inside_the_margin(engine):
    """The judges are not blind: an arm set 5 mm above the table reads 5 mm to both, whichever engine holds it."""
    env = RobotEnv(envfactory.blueprint("UR5ePushSim-v0", engine=engine))
    try:
        env.reset(seed=0)
        q = _pose_above_table(env, 0.005)
        env.backend.reset(q, env.state.gripper, {})
        joints = simulated_joints(env.backend)
        for judge in (MujocoJudge.for_env(env, 0.015), BulletJudge(env, 0.015)):
            value = judge.lowest(joints)
            judge.close()
            assert value[0] == pytest.approx(0.005, abs=0.0015), (type(judge).__name__, value)
    finally:
        env.close()


@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
@pytest.mark.parametrize("ee", [False, True], ids=["joint", "ee"])
@pytest.mark.parametrize("policy", ["random", "extremes", "repeated"])
def test_no_accepted_step_leaves_a_link_inside_the_margin(engine, ee, policy):
    env = RobotEnv(envfactory.blueprint("UR5ePushSim-v0", ee_action_type=ee, engine=engine))
    try:
        result = judge_end_poses(env, policy, 60, seed=7)
    finally:
        env.close()
    assert result["accepted"] >= 10  # the steps judged moved the arm
    assert not result["violations"], result["violations"]
