"""The scripted experts solve their tasks through the env's own action space."""

import pytest

from envfactory.envs.episodes import run_episodes, success_rate
from envfactory.experts import make_policy

REACH_IDS = [
    "UR5eReacherSim-v0",
    "UR5eReacherGoalSim-v0",
    "VX300SReacherSim-v0",
    "VX300SReacherGoalSim-v0",
    "RX200ReacherSim-v0",
    "RX200ReacherGoalSim-v0",
    "NED2ReacherSim-v0",
    "NED2ReacherGoalSim-v0",
    "PandaReachSim-v0",
    "PandaReachGoalSim-v0",
]


@pytest.mark.parametrize("env_id", REACH_IDS)
def test_scripted_reach_succeeds(env_id, make):
    env = make(env_id)
    env.reset(seed=0)
    results = run_episodes(env, make_policy("scripted", env), episodes=20, seed=1000)
    assert success_rate(results) >= 0.9, [(r.seed, r.length, r.success) for r in results]


@pytest.mark.parametrize(
    "env_id", ["UR5eReacherSim-v0", "VX300SReacherSim-v0", "RX200ReacherSim-v0", "PandaReachSim-v0"]
)
def test_scripted_reach_in_ee_mode(env_id, make):
    env = make(env_id, ee_action_type=True)
    env.reset(seed=0)
    results = run_episodes(env, make_policy("scripted", env), episodes=10, seed=2000)
    assert success_rate(results) >= 0.9


MANIPULATION_IDS = [
    "UR5ePushSim-v0",
    "UR5ePnPSim-v0",
    "VX300SPnPSim-v0",
    "RX200PushSim-v0",
    "RX200PnPSim-v0",
    "PandaPushSim-v0",
    "PandaPnPSim-v0",
]


@pytest.mark.parametrize("env_id", MANIPULATION_IDS)
def test_scripted_manipulation_succeeds(env_id, make):
    """A quick sample in the default run; the 50-seed figures are the slow test below."""
    env = make(env_id)
    results = run_episodes(env, make_policy("scripted", env), episodes=6, seed=500)
    assert success_rate(results) >= 5 / 6, [(r.seed, r.length, r.success) for r in results]
    assert sum(r.rejected for r in results) == 0  # the expert never asks for an unsafe motion


@pytest.mark.parametrize("env_id", ["VX300SPushSim-v0", "NED2PushSim-v0", "NED2PnPSim-v0"])
def test_scripted_manipulation_succeeds_near_the_base(env_id, make):
    """As above, less the rejection count: near the base the safety check rightly refuses some of the expert's
    steps. The VX300S's gripper bar (15 cm wide) meets the base when the cube lies close to it; the Ned2's
    forearm folds to within 4 mm of its arm (the makers' meshes; README, "RX200 and Ned2")."""
    env = make(env_id)
    results = run_episodes(env, make_policy("scripted", env), episodes=6, seed=500)
    assert success_rate(results) >= 5 / 6, [(r.seed, r.length, r.success) for r in results]


@pytest.mark.slow
@pytest.mark.parametrize(
    "env_id, bar",
    [
        ("UR5ePushSim-v0", 0.9),
        ("VX300SPushSim-v0", 0.9),
        ("UR5ePnPSim-v0", 0.8),
        ("VX300SPnPSim-v0", 0.8),
        ("RX200PushSim-v0", 0.9),
        ("RX200PnPSim-v0", 0.8),
        ("NED2PushSim-v0", 0.9),
        ("NED2PnPSim-v0", 0.8),
        ("PandaPushSim-v0", 0.9),
        ("PandaPnPSim-v0", 0.8),
    ],
)
def test_scripted_manipulation_over_50_seeds(env_id, bar, make):
    env = make(env_id)
    results = run_episodes(env, make_policy("scripted", env), episodes=50, seed=0)
    assert success_rate(results) >= bar, [(r.seed, r.length) for r in results if not r.success]


@pytest.mark.parametrize(
    "env_id",
    [
        "UR5ePushSim-v0",
        "UR5ePnPSim-v0",
        "VX300SPushSim-v0",
        "VX300SPnPSim-v0",
        "NED2PnPSim-v0",
        "RX200PushSim-v0",
        "PandaPnPSim-v0",
    ],
)
def test_scripted_manipulation_in_ee_mode(env_id, make):
    env = make(env_id, ee_action_type=True)
    results = run_episodes(env, make_policy("scripted", env), episodes=4, seed=700)
    assert success_rate(results) >= 0.75, [(r.seed, r.length, r.success) for r in results]


@pytest.mark.slow
@pytest.mark.parametrize(
    "env_id, bar",
    [
        ("UR5ePushSim-v0", 0.9),
        ("VX300SPushSim-v0", 0.9),
        ("NED2PushSim-v0", 0.9),
        ("RX200PushSim-v0", 0.9),
        ("UR5ePnPSim-v0", 0.8),
        ("VX300SPnPSim-v0", 0.8),
        ("NED2PnPSim-v0", 0.8),
        ("RX200PnPSim-v0", 0.8),
        ("PandaPushSim-v0", 0.9),
        ("PandaPnPSim-v0", 0.8),
    ],
)
def test_scripted_manipulation_in_ee_mode_over_20_seeds(env_id, bar, make):
    """EE mode keeps the gripper pointing down on the arms whose home points it forward, on all four robots
    (the RX200's EE floors sit below the heights its experts push and grasp at: specs/rx200_*.yaml)."""
    env = make(env_id, ee_action_type=True)
    results = run_episodes(env, make_policy("scripted", env), episodes=20, seed=0)
    assert success_rate(results) >= bar, [(r.seed, r.length) for r in results if not r.success]
