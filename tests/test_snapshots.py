"""Spec snapshots: any change to a layout, a bound or a default shows up here.

Update after an intended change with:  pytest tests/test_snapshots.py --snapshot-update
"""

import json

import pytest
from conftest import ALL_IDS
from syrupy.extensions.json import JSONSnapshotExtension

import envfactory
from envfactory.envs.managers import ObservationManager


@pytest.fixture
def snapshot_json(snapshot):
    return snapshot.use_extension(JSONSnapshotExtension)


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_blueprint_snapshot(env_id, snapshot_json):
    assert json.loads(envfactory.blueprint(env_id).to_json()) == snapshot_json


def CUBE_ROWS(start):
    """The five cube rows the Push and Pick-and-Place pages share, from index `start`."""
    components = [
        ("Cube position", "m"),
        ("Cube rpy", "rad"),
        ("Cube linear velocity (finite-diff)", "m/s"),
        ("Cube angular velocity (finite-diff)", "rad/s"),
        ("Cube position relative to EE", "m"),
    ]
    return [(f"{start + 3 * i}–{start + 3 * i + 2}", "3", name, unit) for i, (name, unit) in enumerate(components)]


# The original suite's index tables (Idx, Dim, Component, Unit), row for row.
SEED_TABLES = {
    "UR5eReacherSim-v0": [
        ("0–2", "3", "EE position", "m"),
        ("3–5", "3", "Unit vector EE → goal", "unitless"),
        ("6", "1", "Euclidean distance EE → goal", "m"),
        ("7–13", "7", "Current joint positions", "rad"),
        ("14–19", "6", "Previous action", "matches action space"),
        ("20–26", "7", "Current joint velocities", "rad/s"),
    ],
    "VX300SReacherSim-v0": [
        ("0–2", "3", "EE position", "m"),
        ("3–5", "3", "Unit vector EE → goal", "unitless"),
        ("6", "1", "Euclidean distance EE → goal", "m"),
        ("7–15", "9", "Current joint positions", "rad / m"),
        ("16–21", "6", "Previous action", "matches action space"),
        ("22–30", "9", "Current joint velocities", "rad/s / m/s"),
    ],
    "RX200ReacherSim-v0": [  # the RX200 Reach page's list (it has no index table)
        ("0–2", "3", "EE position", "m"),
        ("3–5", "3", "Unit vector EE → goal", "unitless"),
        ("6", "1", "Euclidean distance EE → goal", "m"),
        ("7–14", "8", "Current joint positions", "rad / m"),
        ("15–19", "5", "Previous action", "matches action space"),
        ("20–27", "8", "Current joint velocities", "rad/s / m/s"),
    ],
    "UR5ePushSim-v0": [
        ("0–2", "3", "EE position", "m"),
        ("3–5", "3", "EE rpy", "rad"),
        ("6–8", "3", "Unit vector cube → goal", "unitless"),
        ("9", "1", "Euclidean distance cube → goal", "m"),
        ("10–16", "7", "Current joint positions", "rad"),
        ("17–22", "6", "Previous action", "matches action space"),
        ("23–29", "7", "Current joint velocities", "rad/s"),
        *CUBE_ROWS(30),
    ],
    "UR5ePnPSim-v0": [
        ("0–2", "3", "EE position", "m"),
        ("3–5", "3", "EE rpy", "rad"),
        ("6–8", "3", "Unit vector cube → current goal", "unitless"),
        ("9", "1", "Euclidean distance cube → current goal", "m"),
        ("10–16", "7", "Current joint positions", "rad"),
        ("17–23", "7", "Previous action", "matches action space"),
        ("24–30", "7", "Current joint velocities", "rad/s"),
        *CUBE_ROWS(31),
        ("46", "1", "is_grasped (derived binary)", "0.0 or 1.0"),
    ],
    "VX300SPushSim-v0": [
        ("0–2", "3", "EE position", "m"),
        ("3–5", "3", "EE rpy", "rad"),
        ("6–8", "3", "Unit vector cube → goal", "unitless"),
        ("9", "1", "Euclidean distance cube → goal", "m"),
        ("10–18", "9", "Current joint positions", "rad / m"),
        ("19–24", "6", "Previous action", "matches action space"),
        ("25–33", "9", "Current joint velocities", "rad/s / m/s"),
        *CUBE_ROWS(34),
    ],
}


@pytest.mark.parametrize("env_id", sorted(SEED_TABLES))
def test_observation_table_matches_seed(env_id):
    rows = ObservationManager(envfactory.blueprint(env_id).policy_observation).table()
    assert [(idx, dim, component, unit) for idx, dim, component, _, unit in rows] == SEED_TABLES[env_id]


def test_ee_mode_shrinks_previous_action():
    # seed: Box(24,) in EE mode for the UR5e standard env
    compiled = envfactory.blueprint("UR5eReacherSim-v0", ee_action_type=True)
    assert compiled.observation_size == 24
    assert compiled.action.size == 3


@pytest.mark.parametrize(
    "env_id, standard, ee_mode, goal_env",
    [
        # the original suite's sizes; EE mode shrinks the previous action to 3 (+1 gripper), goal envs drop the 4
        # goal columns
        ("UR5ePushSim-v0", 45, 42, 41),
        ("UR5ePnPSim-v0", 47, 44, 43),
        ("VX300SPushSim-v0", 49, 46, 45),
        ("VX300SPnPSim-v0", 51, 48, 47),
        # the RX200 pages' layouts: 8 joint_states entries, 5 arm joints
        ("RX200ReacherSim-v0", 28, 26, 24),
        ("RX200PushSim-v0", 46, 44, 42),
        ("RX200PnPSim-v0", 48, 46, 44),
        # the Ned2 pages': 8 joint_states entries, 6 arm joints
        ("NED2ReacherSim-v0", 29, 26, 25),
        ("NED2PushSim-v0", 47, 44, 43),
        ("NED2PnPSim-v0", 49, 46, 45),
        # the Panda's: 9 joint_states entries (7 arm joints, 2 fingers), 7 arm joints
        ("PandaReachSim-v0", 32, 28, 28),
        ("PandaPushSim-v0", 50, 46, 46),
        ("PandaPnPSim-v0", 52, 48, 48),
        # Slide: Push's layout with the puck in the cube's rows
        ("PandaSlideSim-v0", 50, 46, 46),
        ("UR5eSlideSim-v0", 45, 42, 41),
        ("VX300SSlideSim-v0", 49, 46, 45),
        ("RX200SlideSim-v0", 46, 44, 42),
        # Stack: Pick-and-Place's layout with a second cube's 15 rows, is_grasped and goal columns (+20); goal envs
        # drop both cubes' goal columns (8)
        ("UR5eStackSim-v0", 67, 64, 59),
        ("PandaStackSim-v0", 72, 68, 64),
        ("VX300SStackSim-v0", 71, 68, 63),
        ("RX200StackSim-v0", 68, 66, 60),
        ("NED2StackSim-v0", 69, 66, 61),
        # Flip: Pick-and-Place's layout with the turn still to make (goal_rotation 3, goal_angle 1); goal envs drop
        # those with the goal direction and distance (8); EE mode is refused (no EE-mode action turns the cube)
        ("UR5eFlipSim-v0", 51, None, 43),
        ("PandaFlipSim-v0", 56, None, 48),
        ("VX300SFlipSim-v0", 55, None, 47),
        ("NED2FlipSim-v0", 53, None, 45),
        # Drawer: the arm's rows, the handle's point and its offset from the EE, the drawer's joint and its
        # velocity, is_grasped; goal envs drop the goal direction and distance (4)
        ("UR5eDrawerSim-v0", 40, 37, 36),
        ("PandaDrawerSim-v0", 45, 41, 41),
        ("VX300SDrawerSim-v0", 44, 41, 40),
        ("RX200DrawerSim-v0", 41, 39, 37),
        ("NED2DrawerSim-v0", 42, 39, 38),
    ],
)
def test_observation_sizes(env_id, standard, ee_mode, goal_env):
    assert envfactory.blueprint(env_id).observation_size == standard
    if ee_mode is None:
        with pytest.raises(envfactory.SpecError, match="env.action.ee: the goal turns"):
            envfactory.blueprint(env_id, ee_action_type=True)
    else:
        assert envfactory.blueprint(env_id, ee_action_type=True).observation_size == ee_mode
    assert envfactory.blueprint(env_id.replace("Sim", "GoalSim")).observation_size == goal_env


def test_pnp_gripper_is_the_last_action_row_in_both_modes():
    for ee in (False, True):
        action = envfactory.blueprint("UR5ePnPSim-v0", ee_action_type=ee).action
        assert action.size == (4 if ee else 7)
        last = action.rows[-1]
        assert (last.low, last.high, last.joint) == (0.0, 0.8, "robotiq_85_left_knuckle_joint")


def test_goal_env_drops_goal_columns():
    compiled = envfactory.blueprint("UR5eReacherGoalSim-v0")
    assert compiled.observation_size == 27 - 4  # the documented decision: direction and distance dropped
    assert not any(slot.goal_dependent for slot in compiled.policy_observation)
    assert compiled.spec.env.reward_type == "Sparse"


def test_seed_defaults():
    spec = envfactory.blueprint("UR5eReacherSim-v0").spec
    weights = {t.name: t.weight for t in envfactory.blueprint("UR5eReacherSim-v0").rewards}
    assert weights == {
        "distance": -2.0,
        "reached_goal": 20.0,
        "step": -0.5,
        "joint_limits": -2.0,
        "none_exe": -5.0,
        "not_within_goal_space": -2.0,
    }
    assert spec.task.goal.tolerance == 0.02
    assert spec.env.action.delta_coeff == 0.05
    assert spec.env.timing.action_cycle_time == 0.5
    assert spec.env.timing.loop_rate == 10.0
