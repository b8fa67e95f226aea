"""The commands find a user's own robots and IDs: a folder given with --specs serves that command, a folder
recorded by `envfactory register` serves every later process, an unknown name says how to make it known, and a
dataset collected on a user ID recovers its env in a process that never registered the folder."""

from __future__ import annotations

import inspect
import os
import shutil
import subprocess
import sys
from pathlib import Path

import minari
import pytest
from test_robot_folder import _robot_folder
from typer.testing import CliRunner

from envfactory.cli.app import app
from envfactory.cli.common import NAMING_PARAMETERS
from envfactory.factory import unregister_folder
from envfactory.learn.demonstrations import SPEC_FOLDER_KEY, UnrecoverableEnv, _user_spec_folder, load_env
from envfactory.registration import registry

runner = CliRunner()
CLI = str(Path(sys.executable).parent / "envfactory")
USER_ID = "MyArmReach-v0"  # the one ID of the folder test_robot_folder builds, for the robot "myarm"
THREE_WAYS = ("--specs PATH", "envfactory register PATH", "ENVFACTORY_SPEC_PATH=PATH")


@pytest.fixture
def user_folder(tmp_path):
    """A spec folder of one user robot, built from the shipped VX300S; its pair list is not written yet. It is
    unregistered from this process after the test."""
    folder = _robot_folder(tmp_path, packages="  packages: {arm_description: ..}\n")
    robot = folder / "robots" / "myarm.yaml"
    robot.write_text(robot.read_text() + "safety:\n  collision_pairs: assets/myarm.collision.yaml\n")
    yield folder
    unregister_folder(folder)


def _ok(*args):
    result = runner.invoke(app, [str(arg) for arg in args])
    assert result.exit_code == 0, (args, result.output)
    return result.output


def _naming_commands() -> dict[str, object]:
    commands = {}
    for info in app.registered_commands:
        name = info.name or info.callback.__name__.replace("_", "-")
        if any(p in inspect.signature(info.callback).parameters for p in NAMING_PARAMETERS):
            commands[name] = info.callback
    return commands


def test_every_command_naming_a_robot_or_id_takes_specs():
    commands = _naming_commands()
    assert {"run", "collect", "train", "describe", "safety-view", "collision-pairs", "twin"} <= set(commands)
    for name in commands:
        assert "--specs" in _ok(name, "--help"), name


@pytest.mark.parametrize(
    "args, names",
    [
        (["collision-pairs", "myarm"], "no robot or ID named 'myarm' (robots: ned2, panda, rx200, ur5e, vx300s)"),
        (["collision-pairs", "ur5"], "no robot or ID named 'ur5' (did you mean 'ur5e'?)"),
        (
            ["twin", "myarm", "--port", "0"],
            "no robot named 'myarm' (robots with a real path: ned2, rx200, ur5e, vx300s)",
        ),
        (["run", USER_ID, "-n", "1"], f"unknown env ID {USER_ID!r}"),
        (["describe", "UR5eReacherSim-v9"], "unknown env ID 'UR5eReacherSim-v9' (did you mean 'UR5eReacherSim-v0'?)"),
        (["safety-view", "VX300SPushSimm-v0"], "(did you mean 'VX300SPushSim-v0'?)"),
        (["collect", USER_ID, "-n", "1"], f"unknown env ID {USER_ID!r}"),
        (["train", USER_ID, "-n", "100"], f"unknown env ID {USER_ID!r}"),
    ],
)
def test_an_unknown_name_says_how_to_make_it_known(args, names):
    result = runner.invoke(app, args)
    assert result.exit_code == 1, result.output
    text = " ".join(result.output.split())
    assert names in text, text
    assert all(way in text for way in THREE_WAYS), text
    assert "Traceback" not in text


def test_a_specs_path_that_is_no_folder_is_named(tmp_path):
    result = runner.invoke(app, ["describe", "UR5eReacherSim-v0", "--specs", str(tmp_path / "nowhere")])
    assert result.exit_code == 1 and f"--specs {tmp_path / 'nowhere'}: no such spec folder" in result.output


def test_a_family_file_given_as_a_folder_names_its_folder(user_folder):
    """Folders are registered whole: a family file given to register or --specs names the folder to give."""
    family = next((user_folder / "specs").glob("*.yaml"))
    for args in (["register", str(family), "--no-save"], ["describe", USER_ID, "--specs", str(family)]):
        result = runner.invoke(app, args)
        text = " ".join(result.output.split())
        assert result.exit_code == 1 and "is a file, not a spec folder" in text and str(user_folder) in text, text


def test_specs_serves_each_command(user_folder, tmp_path):
    """From a fresh robot: write its pair list, then describe, run and draw its ID, each given the folder."""
    pairs = user_folder / "robots" / "assets" / "myarm.collision.yaml"
    assert USER_ID not in registry.records()
    assert "myarm.collision.yaml: 200 samples" in _ok(
        "collision-pairs", "myarm", "--specs", user_folder, "--samples", 200
    )
    assert pairs.is_file()
    assert f"{USER_ID} — ViperX-300 S, Reach" in _ok("describe", USER_ID, "--specs", user_folder)
    assert "success rate: 100% over 1 episodes" in _ok("run", USER_ID, "--specs", user_folder, "-n", "1")
    out = tmp_path / "myarm.png"
    assert "lowest clearance" in _ok("safety-view", USER_ID, "--specs", user_folder, "--out", out)
    assert out.stat().st_size > 1000


def test_a_folder_recorded_by_register_serves_a_later_process(user_folder, tmp_path, monkeypatch):
    config = tmp_path / "config"
    monkeypatch.setenv("ENVFACTORY_CONFIG_DIR", str(config))
    _ok("collision-pairs", "myarm", "--specs", user_folder, "--samples", 200)  # register validates the list
    assert "recorded" in _ok("register", user_folder)
    pairs = user_folder / "robots" / "assets" / "myarm.collision.yaml"
    pairs.unlink()
    later = subprocess.run(
        [CLI, "collision-pairs", "myarm", "--samples", "200"],
        capture_output=True,
        text=True,
        env={**os.environ, "ENVFACTORY_CONFIG_DIR": str(config)},
        timeout=300,
    )
    assert later.returncode == 0, later.stderr + later.stdout
    assert pairs.is_file()


def test_a_dataset_of_a_user_id_recovers_its_env(user_folder, tmp_path, monkeypatch):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "data"))  # collect sets it; restored after
    _ok("collision-pairs", "myarm", "--specs", user_folder, "--samples", 200)
    written = _ok("collect", USER_ID, "--specs", user_folder, "-n", "2", "--data-path", tmp_path / "data")
    dataset_id = "envfactory/myarmreach/expert-v0"
    assert f"dataset {dataset_id}: 2 episodes" in " ".join(written.split())
    dataset = minari.load_dataset(dataset_id)
    assert dataset.storage.metadata[SPEC_FOLDER_KEY] == str(user_folder.resolve())

    unregister_folder(user_folder)  # as a fresh process finds it: the ID is unknown
    with pytest.raises(KeyError, match="unknown env ID"):
        dataset.recover_environment()  # minari alone cannot make it
    env = load_env(dataset_id)
    try:
        observation, _ = env.reset(seed=0)
        assert env.spec.id == USER_ID and observation.shape == dataset.observation_space.shape
    finally:
        env.close()

    unregister_folder(user_folder)
    shutil.move(user_folder, tmp_path / "moved")
    with pytest.raises(UnrecoverableEnv, match=f"comes from the spec folder {user_folder.resolve()}, which no longer"):
        load_env(dataset)


def test_a_builtin_id_records_no_folder():
    assert _user_spec_folder("UR5eReacherSim-v0") is None


def test_no_command_prints_the_pybullet_banner():
    """PyBullet prints its build time to stderr at import; the CLI drops it and keeps its own errors."""
    result = subprocess.run([CLI, "describe", "NoSuchId-v0"], capture_output=True, text=True, timeout=120)
    assert result.returncode == 1 and "unknown env ID 'NoSuchId-v0'" in result.stderr, result.stderr
    assert "pybullet build time" not in result.stdout + result.stderr
