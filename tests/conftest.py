import os
import tempfile

# Tests never read or write the user's own config (spec folders recorded by `envfactory register`).
os.environ["ENVFACTORY_CONFIG_DIR"] = tempfile.mkdtemp(prefix="envfactory-test-config-")
# ... nor the user's store of compositions: the run starts with none, so both storing and reading are exercised.
os.environ["ENVFACTORY_CACHE_DIR"] = tempfile.mkdtemp(prefix="envfactory-test-cache-")

import gymnasium as gym
import pytest

import envfactory

ALL_IDS = sorted(envfactory.records())
SIM_IDS = sorted(env_id for env_id, record in envfactory.records().items() if record.backend == "sim")
REAL_IDS = sorted(env_id for env_id, record in envfactory.records().items() if record.backend == "rosbridge")


def action_modes(env_id: str) -> tuple[bool, ...]:
    """The ee_action_type values an ID accepts: EE mode is refused where the goal turns an object (Flip), since
    no EE-mode action turns the gripper."""
    return (False,) if envfactory.blueprint(env_id).spec.task.goal.orientation else (False, True)


@pytest.fixture
def make():
    """gym.make that closes every env it opened."""
    opened = []

    def _make(env_id, **kwargs):
        env = gym.make(env_id, **kwargs)
        opened.append(env)
        return env

    yield _make
    for env in opened:
        env.close()


@pytest.fixture
def twin():
    """Start digital twins (robot, task, Twin options); each is stopped after the test."""
    from envfactory.twin import Twin

    started = []

    def start(robot="ur5e", task="push", **options):
        stand_in = Twin(robot, task, **options).start()
        started.append(stand_in)
        return stand_in

    yield start
    for stand_in in started:
        stand_in.stop()
