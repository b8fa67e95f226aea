"""The gripper's step response kept on disk (backends/pybullet/recorded_responses.py) must be the one a fresh
recording gives, and must be recorded again when anything it was made of changes."""

from __future__ import annotations

import gymnasium as gym
import pytest

from envfactory.backends.pybullet import backend as pybullet_backend
from envfactory.backends.pybullet import recorded_responses


@pytest.fixture
def fresh(monkeypatch, tmp_path):
    """An empty config folder, no response remembered in this process, and a count of recordings."""
    monkeypatch.setenv("ENVFACTORY_CONFIG_DIR", str(tmp_path))
    monkeypatch.setattr(pybullet_backend, "_GRIPPER_RESPONSES", {})
    recordings = []
    record = pybullet_backend.PyBulletBackend._record_gripper_response

    def counted(self):
        recordings.append(self.robot.name)
        return record(self)

    monkeypatch.setattr(pybullet_backend.PyBulletBackend, "_record_gripper_response", counted)
    return tmp_path, recordings


def _response(env_id: str, **kwargs):
    env = gym.make(env_id, **kwargs)
    try:
        return env.unwrapped.backend._fast.gripper_response
    finally:
        env.close()


def test_a_kept_response_is_the_recorded_one_and_spares_the_recording(fresh, monkeypatch):
    folder, recordings = fresh
    recorded = _response("VX300SPushSim-v0")
    assert recordings == ["vx300s"] and len(list((folder / recorded_responses.FOLDER).iterdir())) == 1
    monkeypatch.setattr(pybullet_backend, "_GRIPPER_RESPONSES", {})  # as a new process finds it
    kept = _response("VX300SPushSim-v0")
    assert recordings == ["vx300s"]
    assert kept.curves() == recorded.curves() and kept.dt == recorded.dt
    assert len(kept.curves()[0]) > 10


def test_a_changed_gripper_or_physics_step_is_recorded_again(fresh):
    folder, recordings = fresh
    _response("VX300SPushSim-v0")
    _response("VX300SPushSim-v0", overrides=["robot.gripper.force=20.0"])
    _response("VX300SPushSim-v0", overrides=["sim.physics_hz=480"])
    assert recordings == ["vx300s"] * 3
    assert len(list((folder / recorded_responses.FOLDER).iterdir())) == 3
