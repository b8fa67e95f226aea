"""Spec snapshots: any change to a layout, a bound or a default shows up here.

Update after an intended change with:  pytest tests/test_snapshots.py --snapshot-update
"""

import json

import pytest
from syrupy.extensions.json import JSONSnapshotExtension

import envfactory
from conftest import SIM_IDS
from envfactory.managers import ObservationManager


@pytest.fixture
def snapshot_json(snapshot):
    return snapshot.use_extension(JSONSnapshotExtension)


@pytest.mark.parametrize("env_id", SIM_IDS)
def test_blueprint_snapshot(env_id, snapshot_json):
    assert json.loads(envfactory.blueprint(env_id).to_json()) == snapshot_json


# The seed pages' index tables (Idx, Dim, Component, Unit), row for row.
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


def test_goal_env_drops_goal_columns():
    compiled = envfactory.blueprint("UR5eReacherGoalSim-v0")
    assert compiled.observation_size == 27 - 4  # the documented decision: direction and distance dropped
    assert not any(slot.goal_dependent for slot in compiled.policy_observation)
    assert compiled.spec.env.reward_type == "Sparse"


def test_seed_defaults():
    spec = envfactory.blueprint("UR5eReacherSim-v0").spec
    weights = {t.name: t.weight for t in envfactory.blueprint("UR5eReacherSim-v0").rewards}
    assert weights == {"distance": -2.0, "reached_goal": 20.0, "step": -0.5, "joint_limits": -2.0,
                       "none_exe": -5.0, "not_within_goal_space": -2.0}
    assert spec.task.goal.tolerance == 0.02
    assert spec.env.action.delta_coeff == 0.05
    assert spec.env.timing.action_cycle_time == 0.5
    assert spec.env.timing.loop_rate == 10.0
