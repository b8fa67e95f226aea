"""The cluster wing without a cluster: the work a Ray task does, run in this process; folders that travel to
workers; the commands without Ray installed; and the rule that only envfactory/cluster/ imports Ray.

tests/test_cluster.py runs the same work on a local Ray instance."""

from __future__ import annotations

import ast
import csv
import shutil
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from test_robot_folder import _robot_folder
from typer.testing import CliRunner

from envfactory import cluster
from envfactory.cli.app import app
from envfactory.cluster import bundles, trials
from envfactory.cluster.work import Collection, SeedEvaluation, ShippedFolders, ShippedFoldersError, run_here, split
from envfactory.experts import make_policy
from envfactory.factory import unregister_folder
from envfactory.learn import extra
from envfactory.learn.hyperparams import HyperparameterError
from envfactory.registration import registry

runner = CliRunner()
PACKAGE = Path(__file__).resolve().parents[1] / "envfactory"
REACH = "UR5eReacherSim-v0"  # 100-step episodes in a few tens of ms
needs_minari = pytest.mark.skipif(
    bool(extra.missing(extra.COLLECT_MODULES)),
    reason="the [train] extra (minari) is not installed (pip install -e '.[train]')",
)


@pytest.fixture
def user_folder(tmp_path):
    """A spec folder of one user robot (MyArmReach-v0), registered in this process only: no variable, no config."""
    folder = _robot_folder(tmp_path, packages="  packages: {arm_description: ..}\n")
    yield folder
    unregister_folder(folder)


def test_only_the_cluster_wing_imports_ray():
    """Every `import ray` of the package is at the top of a module in envfactory/cluster/."""
    found = []
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = (
                [alias.name for alias in node.names]
                if isinstance(node, ast.Import)
                else [node.module or ""]
                if isinstance(node, ast.ImportFrom)
                else []
            )
            if any(name == "ray" or name.startswith("ray.") for name in names):
                found.append(path.relative_to(PACKAGE).parts[0])
    assert found and set(found) == {"cluster"}


def test_the_command_does_not_import_ray():
    done = subprocess.run(
        [sys.executable, "-c", "import sys, envfactory.cli.app; print('ray' in sys.modules)"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "False"


@pytest.mark.parametrize(
    "args",
    [
        ["evaluate", REACH, "-n", "1", "--workers", "2"],
        ["collect", REACH, "-n", "1", "--address", "auto"],
        ["train", REACH, "--seeds", "0,1", "--steps", "100", "--workers", "2"],
    ],
)
def test_without_ray_a_cluster_run_says_how_to_install_it(monkeypatch, tmp_path, args):
    monkeypatch.setitem(cluster.RAY_MODULES, "envfactory_no_such_module", "ray")
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(app, args)
    assert result.exit_code == 1, result.output
    text = " ".join(result.output.split())
    assert "needs the [ray] extra" in text and "pip install 'envfactory[ray]'" in text, text
    assert "Traceback" not in text


def test_split_covers_every_seed_once():
    for count, pieces in [(10, 3), (3, 8), (1, 1), (64, 8)]:
        parts = split(range(5, 5 + count), pieces)
        assert len(parts) <= pieces
        assert [seed for part in parts for seed in part] == list(range(5, 5 + count))


def test_evaluation_ranges_merged_in_any_order_equal_one_run():
    work = SeedEvaluation(REACH, {"ee_action_type": True})
    whole = run_here(work, range(3, 9))
    first, second = work(range(3, 5)), work(range(5, 9))
    assert work.merge([second, first]) == whole
    assert [r.index for r in whole] == list(range(6)) and [r.seed for r in whole] == list(range(3, 9))
    assert len({r.episode_return for r in whole}) > 1  # different goals: the seeds do reach the episodes
    # and one run is what a bare gymnasium loop over the same seeds gives, the scripted expert acting
    env = gym.make(REACH, ee_action_type=True)
    try:
        returns = []
        for seed in range(3, 9):
            observation, _ = env.reset(seed=seed)
            policy, total, ended = make_policy("scripted", env), 0.0, False
            while not ended:
                observation, reward, terminated, truncated, _ = env.step(policy(observation))
                total, ended = total + float(reward), terminated or truncated
            returns.append(total)
    finally:
        env.close()
    assert np.allclose([r.episode_return for r in whole], returns)


@needs_minari
@pytest.mark.parametrize("action_noise", [0.0, 0.2])
def test_collection_ranges_merged_in_any_order_equal_one_run(action_noise):
    work = Collection("UR5eReacherGoalSim-v0", action_noise=action_noise)
    whole = run_here(work, range(0, 4))
    assert whole.action_noise == action_noise
    merged = work.merge([work(range(2, 4)), work(range(0, 2))])
    assert merged.results == whole.results and merged.env_spec == whole.env_spec
    for ours, theirs in zip(merged.episodes, whole.episodes):
        assert ours["seed"] == theirs["seed"]
        assert np.array_equal(np.array(ours["actions"]), np.array(theirs["actions"]))
        assert ours["rewards"] == theirs["rewards"]


def test_a_folder_copy_is_its_origin_where_that_holds_the_same_files(tmp_path):
    folder = tmp_path / "specs_here"
    (folder / "sub").mkdir(parents=True)
    (folder / "sub" / "a.yaml").write_text("a: 1\n")
    (folder / "__pycache__").mkdir()
    (folder / "__pycache__" / "x.pyc").write_bytes(b"\0")
    copy = bundles.FolderCopy.pack(folder)
    assert [name for name, _ in copy.files] == ["sub/a.yaml"]
    assert copy.where() == folder.resolve()
    (folder / "sub" / "a.yaml").write_text("a: 2\n")  # changed since packed: the packed files win
    elsewhere = copy.where()
    assert elsewhere != folder.resolve() and (elsewhere / "sub" / "a.yaml").read_text() == "a: 1\n"
    shutil.rmtree(elsewhere.parent)


def test_a_missing_folder_cannot_travel(tmp_path):
    with pytest.raises(bundles.FolderCopyError, match="no such folder"):
        bundles.FolderCopy.pack(tmp_path / "nowhere")


def test_a_user_id_is_made_from_its_folder_copy_where_the_folder_is_gone(user_folder, tmp_path):
    """What a worker on another machine does: the folder is not at its path there, so the copy sent with the
    job is written out and registered, and the ID makes and runs."""
    registry.register_folder(user_folder)
    workspace = ShippedFolders.for_ids(["MyArmReach-v0"])
    here = run_here(SeedEvaluation("MyArmReach-v0", {}, workspace), range(0, 2))
    unregister_folder(user_folder)
    moved = user_folder.rename(tmp_path / "moved")
    try:
        assert "MyArmReach-v0" not in registry.records()
        elsewhere = run_here(SeedEvaluation("MyArmReach-v0", {}, workspace), range(0, 2))
        copy = Path(registry.record("MyArmReach-v0").family.path).parents[1]
        assert bundles.CACHE_FOLDER in copy.parts and copy.name == "robotdir"
        assert elsewhere == here
    finally:
        unregister_folder(registry.record("MyArmReach-v0").family.path.parents[1])
        moved.rename(user_folder)


def test_evaluate_prints_a_success_table_and_every_episode(tmp_path, user_folder):
    out = tmp_path / "episodes.csv"
    result = runner.invoke(
        app,
        [
            "evaluate",
            REACH,
            "MyArmReach-v0",
            "-n",
            "2",
            "--seed",
            "4",
            "--csv",
            str(out),
            "--specs",
            str(user_folder),
            "--no-progress",
        ],
    )
    assert result.exit_code == 0, result.output
    assert "MyArmReach-v0" in result.output and "success rate:" in result.output
    rows = list(csv.DictReader(open(out)))
    assert [(r["env_id"], int(r["seed"])) for r in rows] == [
        (REACH, 4),
        (REACH, 5),
        ("MyArmReach-v0", 4),
        ("MyArmReach-v0", 5),
    ]
    assert all(int(r["length"]) > 0 for r in rows)


@pytest.mark.parametrize(
    "args, message",
    [
        (["evaluate", "UR5eReacherReal-v0", "-n", "1"], "drives a real arm for every episode: clear the workspace"),
        (
            ["evaluate", "UR5eReacherReal-v0", "--allow-real-robot-motion", "--workers", "2"],
            "drives a real arm: it runs here, one episode after another (drop --workers/--address)",
        ),
        (["collect", "UR5eReacherReal-v0"], "collect runs simulated IDs only"),
        (["evaluate", REACH, "--policy", "random"], "use 'scripted' or a model file (.zip)"),
        (["evaluate", REACH, "--policy", "nowhere/model.zip"], "no such file"),
        (["evaluate", REACH, "--csv", "out.txt"], "must end in one of .csv"),
        (["train", REACH, "--workers", "2"], "--workers and --address spread several runs: give --seeds"),
        (["train", REACH, "--seeds", "0,x"], "write whole numbers separated by commas"),
        (["train", REACH, "--seeds", "0,1", "--seed", "3"], "drop --resume and --seed"),
        (["train", REACH, "--sweep", "learning_rate"], "write name=value1,value2"),
    ],
)
def test_bad_cluster_options_are_named(tmp_path, monkeypatch, args, message):
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(app, args)
    text = " ".join(result.output.split())
    assert result.exit_code == 1 and message in text, text
    assert "Traceback" not in text
    assert not (tmp_path / "runs").exists()  # refused before any folder was made


def test_trials_that_fail_are_named_in_the_summary_and_the_others_go_on(tmp_path, monkeypatch):
    """An option the policy network does not take passes every check of the settings (policy_kwargs go to the
    policy class as they are) and is found as each trial builds its model: every trial says so."""
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(
        app, ["train", REACH, "--seeds", "0", "--sweep", "policy_kwargs.no_such_option=1,2", "--no-progress"]
    )
    text = " ".join(result.output.split())
    assert result.exit_code == 1 and "2 of 2 trials failed" in text and "no_such_option" in text, text
    rows = list(csv.DictReader(open(tmp_path / "runs" / f"{REACH}-sac-seeds0" / trials.SUMMARY_FILE)))
    assert [r["trial"] for r in rows] == [
        "seed0-policy_kwargs.no_such_option=1",
        "seed0-policy_kwargs.no_such_option=2",
    ]
    assert all(r["error"].startswith("TypeError: ") and "no_such_option" in r["error"] for r in rows), rows


def test_sweep_values_keep_their_brackets():
    assert trials.parse_sweep(["learning_rate=0.001,0.0003", "policy_kwargs.net_arch=[64,64],[256,256]"]) == {
        "learning_rate": ["0.001", "0.0003"],
        "policy_kwargs.net_arch": ["[64,64]", "[256,256]"],
    }
    with pytest.raises(HyperparameterError, match="given twice"):
        trials.parse_sweep(["tau=0.1", "tau=0.2"])
    with pytest.raises(HyperparameterError, match="name=value1,value2"):
        trials.parse_sweep(["tau=0.1,"])


def test_the_plan_is_seeds_times_settings_in_their_own_folders(tmp_path):
    planned = trials.plan(
        REACH, tmp_path / "group", [0, 1], {"learning_rate": ["0.001", "0.0003"]}, "sac", (), 100, {}, None, None, None
    )
    assert [Path(t.folder).name for t in planned] == [
        "seed0-learning_rate=0.001",
        "seed1-learning_rate=0.001",
        "seed0-learning_rate=0.0003",
        "seed1-learning_rate=0.0003",
    ]
    assert all(Path(t.folder).is_absolute() for t in planned)


def test_a_trial_refuses_a_group_folder_it_cannot_see(tmp_path):
    """On a machine without the head's filesystem the marker is not there: the trial says so, trains nothing."""
    planned = trials.plan(REACH, tmp_path / "group", [0], {}, "sac", (), 100, {}, None, None, None)
    with pytest.raises(trials.TrialError, match="does not see the group folder"):
        trials.run_trial(planned[0])
    trials.open_group(tmp_path / "group", planned)
    (tmp_path / "group" / trials.MARKER_FILE).write_text("another run's token")
    outcome = trials.run_here(planned)[0]
    assert "does not see the group folder" in outcome.error and not Path(planned[0].folder).exists()


def test_a_worker_never_runs_an_id_from_another_folder_than_the_jobs(user_folder, tmp_path):
    """A machine whose own folders (ENVFACTORY_SPEC_PATH, `envfactory register`) declare the same ID elsewhere
    would run other specs than the head's: the work refuses, naming both folders."""
    registry.register_folder(user_folder)
    workspace = ShippedFolders.for_ids(["MyArmReach-v0"])
    unregister_folder(user_folder)
    other = shutil.copytree(user_folder, tmp_path / "other")
    registry.register_folder(other)
    try:
        with pytest.raises(ShippedFoldersError, match=r"registers it from .*other, not from the job's spec folder"):
            run_here(SeedEvaluation("MyArmReach-v0", {}, workspace), range(0, 1))
    finally:
        unregister_folder(other)
