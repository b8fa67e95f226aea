"""Smoke tests of the learning pipeline: train -> saved model -> replay, and expert episodes -> Minari dataset.

They need the [train] extra and are skipped (with the reason) without it. The
learning itself is measured by benchmarks/learning.py, not here.
"""

import csv
import json

import numpy as np
import pytest
from typer.testing import CliRunner

from envfactory.cli.main import app
from envfactory.learn import extra
from envfactory.learn.hyperparams import HyperparameterError, load, parse_overrides

runner = CliRunner()
needs_train = pytest.mark.skipif(bool(extra.missing({**extra.TRAIN_MODULES, **extra.PLOT_MODULES})),
                                 reason="the [train] extra is not installed (pip install -e '.[train]')")
needs_minari = pytest.mark.skipif(bool(extra.missing(extra.COLLECT_MODULES)),
                                  reason="the [train] extra (minari) is not installed (pip install -e '.[train]')")

# a tiny, fast configuration: the pipeline is under test, not the learning
TINY = ["-p", "learning_starts=110", "-p", "batch_size=32", "-p", "buffer_size=2000",
        "-p", "policy_kwargs.net_arch=[32,32]"]


@needs_train
@pytest.mark.parametrize("algo", ["sac", "td3", "tqc"])
def test_train_saves_a_model_and_a_curve_that_run_replays(tmp_path, algo):
    folder = tmp_path / "run"
    result = runner.invoke(app, ["train", "VX300SReacherGoalSim-v0", "--algo", algo, "--steps", "240",
                                 "--eval-every", "120", "--eval-episodes", "2", "--no-progress", "-o", str(folder),
                                 *TINY])
    assert result.exit_code == 0, result.output
    rows = list(csv.DictReader(open(folder / "curve.csv")))
    assert [int(r["timesteps"]) for r in rows] == [120, 240]
    assert all(0.0 <= float(r["success_rate"]) <= 1.0 and int(r["episodes"]) == 2 for r in rows)
    assert (folder / "curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    meta = json.loads((folder / "model.json").read_text())
    assert meta["algo"] == algo
    # the default block's kwargs, updated by the vx300s_reach family block
    assert meta["env_kwargs"] == {"ee_action_type": True, "normalize_actions": True, "normalize_observations": True,
                                  "delta_coeff": 0.035}
    assert meta["hyperparameters"]["batch_size"] == 32  # the command line won over the YAML's 256

    video = tmp_path / "replay.mp4"
    replay = runner.invoke(app, ["run", "VX300SReacherGoalSim-v0", "--policy", str(folder / "model.zip"), "-n", "1",
                                 "--video", str(video)])
    assert replay.exit_code == 0, replay.output
    assert "success rate" in replay.output and video.stat().st_size > 1000


@needs_train
def test_replayed_model_acts_as_the_saved_network(tmp_path):
    """The policy `run` replays is the trained one: its actions equal SB3's own load of the file."""
    import gymnasium as gym
    from stable_baselines3 import SAC
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from envfactory.learn.trainer import load_policy, train

    train("VX300SReacherGoalSim-v0", tmp_path, steps=120, eval_every=120, eval_episodes=1, progress_bar=False,
          overrides=("learning_starts=110", "batch_size=32", "policy_kwargs.net_arch=[32,32]", "normalize=true"))
    env = gym.make("VX300SReacherGoalSim-v0", ee_action_type=True, normalize_actions=True, normalize_observations=True)
    try:
        observation, _ = env.reset(seed=3)
        policy = load_policy(tmp_path / "model.zip", env)
        reference = SAC.load(tmp_path / "model.zip", env=env)
        # trained with `normalize`: SB3's own statistics file scales what the network sees
        scaling = VecNormalize.load(str(tmp_path / "vecnormalize.pkl"), DummyVecEnv([lambda: env]))
        scaling.training = False
        expected = reference.predict(scaling.normalize_obs(observation), deterministic=True)[0]
        assert np.array_equal(policy(observation), expected)
        assert not np.array_equal(reference.predict(observation, deterministic=True)[0], expected)  # it matters
    finally:
        env.close()


@needs_train
def test_run_refuses_a_model_trained_on_other_spaces(tmp_path):
    from envfactory.learn.trainer import train

    train("VX300SReacherGoalSim-v0", tmp_path, steps=120, eval_every=120, eval_episodes=1, progress_bar=False,
          overrides=("learning_starts=110", "batch_size=32", "policy_kwargs.net_arch=[32,32]"))
    result = runner.invoke(app, ["run", "VX300SReacherGoalSim-v0", "--policy", str(tmp_path / "model.zip"),
                                 "-k", "ee_action_type=false"])
    assert result.exit_code == 1
    assert "cannot act in VX300SReacherGoalSim-v0 (action shape (6,)" in result.output
    assert "Traceback" not in result.output


def test_hyperparameters_merge_default_family_and_command_line():
    hyper = load("sac", "UR5eReacherGoalSim-v0", ["gamma=0.9", "policy_kwargs.net_arch=[64, 64]", "her.n_sampled_goal=8"])
    assert hyper.values["gamma"] == 0.9 and hyper.values["policy_kwargs"]["net_arch"] == [64, 64]
    assert hyper.values["her"] == {"n_sampled_goal": 8, "goal_selection_strategy": "future"}  # merged, not replaced
    assert hyper.sources[0].endswith("sac.yaml: default") and hyper.sources[-1].startswith("command line")
    assert "env_kwargs" not in hyper.algorithm_kwargs() and "her" not in hyper.algorithm_kwargs()


def test_family_and_id_blocks_override_the_default(tmp_path, monkeypatch):
    import envfactory.learn.hyperparams as hp

    (tmp_path / "sac.yaml").write_text("default: {gamma: 0.95, batch_size: 256}\n"
                                       "ur5e_reach: {gamma: 0.9}\n"
                                       "UR5eReacherGoalSim-v0: {batch_size: 64}\n")
    monkeypatch.setattr(hp, "builtin_folder", lambda: tmp_path)
    assert load("sac", "UR5eReacherGoalSim-v0").values == {"gamma": 0.9, "batch_size": 64}
    assert load("sac", "UR5eReacherSim-v0").values == {"gamma": 0.9, "batch_size": 256}
    assert load("sac", "VX300SReacherSim-v0").values == {"gamma": 0.95, "batch_size": 256}


def test_bad_hyperparameters_are_named(tmp_path, monkeypatch):
    import envfactory.learn.hyperparams as hp

    with pytest.raises(HyperparameterError, match="write name=value"):
        parse_overrides(["gamma"])
    with pytest.raises(HyperparameterError, match="algorithm 'ppo'"):
        load("ppo", "UR5eReacherGoalSim-v0")
    (tmp_path / "sac.yaml").write_text("default:\n  gamma: [0.9\n")
    monkeypatch.setattr(hp, "builtin_folder", lambda: tmp_path)
    with pytest.raises(HyperparameterError, match=r"sac.yaml:\d+: not valid YAML"):
        load("sac", "UR5eReacherGoalSim-v0")


@needs_train
def test_her_learning_starts_within_the_first_episode_is_refused(tmp_path):
    result = runner.invoke(app, ["train", "VX300SReacherGoalSim-v0", "-p", "learning_starts=50", "-o", str(tmp_path)])
    assert result.exit_code == 1
    assert "learning_starts=50 must exceed the episode limit of VX300SReacherGoalSim-v0 (100 steps)" in result.output


@needs_train
def test_unknown_hyperparameter_fails_before_training(tmp_path):
    result = runner.invoke(app, ["train", "VX300SReacherGoalSim-v0", "-p", "learning_rat=0.1", "-o", str(tmp_path)])
    assert result.exit_code == 1
    assert "unknown hyperparameter(s) learning_rat" in result.output and "command line" in result.output
    assert not (tmp_path / "model.zip").exists()


def test_missing_extra_is_a_clear_error(monkeypatch):
    monkeypatch.setitem(extra.TRAIN_MODULES, "envfactory_no_such_module", "no-such-package")
    result = runner.invoke(app, ["train", "VX300SReacherGoalSim-v0"])
    assert result.exit_code == 1
    assert "needs the [train] extra (no-such-package not installed)" in result.output
    assert "pip install -e '.[train]'" in result.output and "Traceback" not in result.output


@needs_minari
@pytest.mark.parametrize("kwargs", [[], ["-k", "ee_action_type=true", "-k", "normalize_actions=true"]])
def test_collect_writes_a_minari_dataset_that_loads_back(tmp_path, monkeypatch, kwargs):
    import minari

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    result = runner.invoke(app, ["collect", "UR5eReacherGoalSim-v0", "--episodes", "4", "--data-path", str(tmp_path),
                                 *kwargs])
    assert result.exit_code == 0, result.output
    dataset = minari.load_dataset("envfactory/ur5ereachergoalsim/expert-v0")
    assert dataset.total_episodes == 4
    env = dataset.recover_environment()
    try:
        for episode in dataset.iterate_episodes():
            obs = episode.observations
            assert len(obs["observation"]) == len(episode.actions) + 1
            assert all(env.action_space.contains(a) for a in episode.actions)
            # the seed's sparse reward, recomputed from the recorded goals: 0 within 2 cm, else -1
            distance = np.linalg.norm(obs["achieved_goal"][1:] - obs["desired_goal"][1:], axis=1)
            assert np.array_equal(episode.rewards, np.where(distance < 0.02, 0.0, -1.0))
            assert episode.terminations[-1] and distance[-1] < 0.02  # the expert reaches every goal
            # success per step, judged against the recorded goals (2 cm tolerance)
            assert np.array_equal(episode.infos["is_success"][1:], distance < 0.02)
    finally:
        env.close()

    again = runner.invoke(app, ["collect", "UR5eReacherGoalSim-v0", "--episodes", "1", "--data-path", str(tmp_path)])
    assert again.exit_code == 1 and "already exists" in again.output and "--overwrite" in again.output
