"""The scripted Reach expert solves every Reacher ID through the env's own action space."""

import pytest

from envfactory.episodes import run_episodes, success_rate
from envfactory.experts import make_policy

REACH_IDS = ["UR5eReacherSim-v0", "UR5eReacherGoalSim-v0", "VX300SReacherSim-v0", "VX300SReacherGoalSim-v0"]


@pytest.mark.parametrize("env_id", REACH_IDS)
def test_scripted_reach_succeeds(env_id, make):
    env = make(env_id)
    env.reset(seed=0)
    results = run_episodes(env, make_policy("scripted", env), episodes=20, seed=1000)
    assert success_rate(results) >= 0.9, [(r.seed, r.length, r.success) for r in results]


@pytest.mark.parametrize("env_id", ["UR5eReacherSim-v0", "VX300SReacherSim-v0"])
def test_scripted_reach_in_ee_mode(env_id, make):
    env = make(env_id, ee_action_type=True)
    env.reset(seed=0)
    results = run_episodes(env, make_policy("scripted", env), episodes=10, seed=2000)
    assert success_rate(results) >= 0.9
