"""Tests of the learning pipeline: train -> saved model -> replay; run folders never overwritten; a run stopped and
resumed; model.json; TensorBoard; nothing left by a failed start; expert episodes -> Minari dataset, without warnings.

They need the [train] extra and are skipped (with the reason) without it. The
learning itself is measured by devkit/bench/learning.py, not here.
"""

import csv
import json

import numpy as np
import pytest
from typer.testing import CliRunner

from envfactory.cli.app import app
from envfactory.learn import extra
from envfactory.learn.hyperparams import HyperparameterError, load, parse_overrides

runner = CliRunner()
needs_train = pytest.mark.skipif(
    bool(extra.missing({**extra.TRAIN_MODULES, **extra.PLOT_MODULES})),
    reason="the [train] extra is not installed (pip install -e '.[train]')",
)
needs_minari = pytest.mark.skipif(
    bool(extra.missing(extra.COLLECT_MODULES)),
    reason="the [train] extra (minari) is not installed (pip install -e '.[train]')",
)

# a tiny, fast configuration: the pipeline is under test, not the learning
TINY = [
    "-p",
    "learning_starts=110",
    "-p",
    "batch_size=32",
    "-p",
    "buffer_size=2000",
    "-p",
    "policy_kwargs.net_arch=[32,32]",
]


@needs_train
@pytest.mark.parametrize("algo", ["sac", "td3", "tqc"])
def test_train_saves_a_model_and_a_curve_that_run_replays(tmp_path, algo):
    folder = tmp_path / "run"
    result = runner.invoke(
        app,
        [
            "train",
            "VX300SReacherGoalSim-v0",
            "--algo",
            algo,
            "--steps",
            "240",
            "--eval-every",
            "120",
            "--eval-episodes",
            "2",
            "--no-progress",
            "--out",
            str(folder),
            *TINY,
        ],
    )
    assert result.exit_code == 0, result.output
    rows = list(csv.DictReader(open(folder / "curve.csv")))
    assert [int(r["timesteps"]) for r in rows] == [120, 240]
    assert all(0.0 <= float(r["success_rate"]) <= 1.0 and int(r["episodes"]) == 2 for r in rows)
    assert (folder / "curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    meta = json.loads((folder / "model.json").read_text())
    assert meta["algo"] == algo
    # the default block's kwargs, updated by the vx300s_reach family block
    assert meta["env_kwargs"] == {
        "ee_action_type": True,
        "normalize_actions": True,
        "normalize_observations": True,
        "delta_coeff": 0.035,
    }
    assert meta["hyperparameters"]["batch_size"] == 32  # the command line won over the YAML's 256

    video = tmp_path / "replay.mp4"
    replay = runner.invoke(
        app, ["run", "VX300SReacherGoalSim-v0", "--policy", str(folder / "model.zip"), "-n", "1", "--video", str(video)]
    )
    assert replay.exit_code == 0, replay.output
    assert "success rate" in replay.output and video.stat().st_size > 1000


@needs_train
def test_replayed_model_acts_as_the_saved_network(tmp_path):
    """The policy `run` replays is the trained one: its actions equal SB3's own load of the file."""
    import gymnasium as gym
    from stable_baselines3 import SAC
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from envfactory.learn.trainer import load_policy, train

    train(
        "VX300SReacherGoalSim-v0",
        tmp_path,
        steps=120,
        eval_every=120,
        eval_episodes=1,
        progress_bar=False,
        overrides=("learning_starts=110", "batch_size=32", "policy_kwargs.net_arch=[32,32]", "normalize=true"),
    )
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
def test_run_and_evaluate_refuse_a_model_trained_on_other_spaces(tmp_path):
    from envfactory.learn.trainer import train

    train(
        "VX300SReacherGoalSim-v0",
        tmp_path,
        steps=120,
        eval_every=120,
        eval_episodes=1,
        progress_bar=False,
        overrides=("learning_starts=110", "batch_size=32", "policy_kwargs.net_arch=[32,32]"),
    )
    result = runner.invoke(
        app, ["run", "VX300SReacherGoalSim-v0", "--policy", str(tmp_path / "model.zip"), "-k", "ee_action_type=false"]
    )
    assert result.exit_code == 1
    assert "cannot act in VX300SReacherGoalSim-v0 (action shape (6,)" in result.output
    assert "Traceback" not in result.output
    # evaluate loads it as run does: a model of another robot is named with the spaces it met
    result = runner.invoke(
        app, ["evaluate", "UR5eReacherGoalSim-v0", "--policy", str(tmp_path / "model.zip"), "-n", "1", "--no-progress"]
    )
    assert result.exit_code == 1
    output = " ".join(result.output.split())
    assert "cannot act in UR5eReacherGoalSim-v0 (action shape" in output and "Observation spaces do not match" in output
    assert "Traceback" not in output


def _tiny_run(folder, *extra_args, steps="240"):
    return runner.invoke(
        app,
        [
            "train",
            "VX300SReacherGoalSim-v0",
            "--steps",
            steps,
            "--eval-every",
            "120",
            "--eval-episodes",
            "1",
            "--no-progress",
            "--out",
            str(folder),
            *TINY,
            *extra_args,
        ],
    )


@needs_train
def test_a_second_run_never_overwrites_the_first(tmp_path):
    first = _tiny_run(tmp_path / "run", steps="120")
    assert first.exit_code == 0, first.output
    model = (tmp_path / "run" / "model.zip").read_bytes()
    second = _tiny_run(tmp_path / "run", "--seed", "1", steps="120")
    assert second.exit_code == 0, second.output
    assert (
        f"{tmp_path / 'run'} holds an earlier run, which is never overwritten: this run goes to "
        f"{tmp_path / 'run-2'}" in second.output.replace("\n", "")
    )
    assert (tmp_path / "run" / "model.zip").read_bytes() == model
    assert json.loads((tmp_path / "run-2" / "model.json").read_text())["seed"] == 1

    from envfactory.learn.runs import RunFolderError, claim

    with pytest.raises(RunFolderError, match="holds an earlier run"):  # the library refuses it too
        claim(tmp_path / "run")


@needs_train
def test_model_json_records_every_setting_that_shaped_the_run(tmp_path):
    result = _tiny_run(tmp_path / "run", "-k", "delta_coeff=0.03", "--seed", "3", steps="120")
    assert result.exit_code == 0, result.output
    meta = json.loads((tmp_path / "run" / "model.json").read_text())
    assert (meta["seed"], meta["steps"], meta["eval_every"], meta["eval_episodes"]) == (3, 120, 120, 1)
    assert meta["kwargs"] == {"delta_coeff": 0.03} and meta["env_kwargs"]["delta_coeff"] == 0.03
    assert meta["overrides"] == TINY[1::2]
    # the merged hyperparameters, and exactly what the algorithm's constructor was given
    assert (
        meta["hyperparameters"]["policy_kwargs"] == {"net_arch": [32, 32]} and meta["hyperparameters"]["gamma"] == 0.95
    )
    assert meta["algorithm_kwargs"]["replay_buffer_class"] == "HerReplayBuffer"
    assert meta["algorithm_kwargs"]["replay_buffer_kwargs"] == {
        "n_sampled_goal": 4,
        "goal_selection_strategy": "future",
    }
    assert meta["demos"] is None and meta["normalize"] is False
    part = meta["parts"][0]
    assert part["status"] == "finished" and part["from_timesteps"] == 0 and part["timesteps"] == 120
    assert part["versions"]["stable-baselines3"] and part["versions"]["torch"] and part["versions"]["envfactory"]
    # the recorded command repeats the run
    assert meta["command"].startswith(
        "envfactory train VX300SReacherGoalSim-v0 --algo sac --seed 3 --steps 120 "
        "--eval-every 120 --eval-episodes 1 -p learning_starts=110"
    )
    assert "-k delta_coeff=0.03" in meta["command"]


@needs_train
def test_resume_continues_the_model_buffer_statistics_and_curve(tmp_path):
    import pickle

    folder = tmp_path / "run"
    first = _tiny_run(folder, "-p", "normalize=true")
    assert first.exit_code == 0, first.output
    with open(folder / "replay_buffer.pkl", "rb") as handle:
        saved = pickle.load(handle)
    with open(folder / "vecnormalize.pkl", "rb") as handle:
        count = pickle.load(handle).obs_rms["observation"].count

    again = runner.invoke(app, ["train", "--resume", str(folder), "--steps", "480", "--no-progress"])
    assert again.exit_code == 0, again.output
    rows = list(csv.DictReader(open(folder / "curve.csv")))
    assert [int(r["timesteps"]) for r in rows] == [120, 240, 360, 480]  # the curve goes on from its last step
    walls = [float(r["wall_s"]) for r in rows]
    assert walls == sorted(walls) and walls[2] > walls[1]  # wall-clock time adds up over the parts
    with open(folder / "replay_buffer.pkl", "rb") as handle:
        resumed = pickle.load(handle)
    assert resumed.pos == 480  # the buffer holds both parts' steps, the first part's unchanged
    assert np.array_equal(resumed.observations["observation"][:240], saved.observations["observation"][:240])
    with open(folder / "vecnormalize.pkl", "rb") as handle:
        assert pickle.load(handle).obs_rms["observation"].count > count + 200  # statistics went on, not restarted
    meta = json.loads((folder / "model.json").read_text())
    assert [(p["from_timesteps"], p["target_timesteps"], p["status"]) for p in meta["parts"]] == [
        (0, 240, "finished"),
        (240, 480, "finished"),
    ]
    assert meta["timesteps"] == 480 and meta["steps"] == 480

    from stable_baselines3.common.save_util import load_from_zip_file

    assert load_from_zip_file(folder / "model.zip")[0]["num_timesteps"] == 480  # the model itself went on


@needs_train
def test_a_stopped_run_saves_where_it_stands_and_resumes(tmp_path):
    from envfactory.learn.trainer import resume, train

    def stop(row):
        raise KeyboardInterrupt  # Ctrl-C (or SIGTERM) during the run

    with pytest.raises(KeyboardInterrupt):
        train(
            "VX300SReacherGoalSim-v0",
            tmp_path,
            steps=360,
            eval_every=120,
            eval_episodes=1,
            progress_bar=False,
            overrides=tuple(TINY[1::2]),
            on_evaluation=stop,
        )
    meta = json.loads((tmp_path / "model.json").read_text())
    assert meta["parts"][0]["status"] == "interrupted" and meta["timesteps"] == 120
    assert (tmp_path / "replay_buffer.pkl").is_file() and meta["replay_buffer_timesteps"] == 120
    result = resume(tmp_path, progress_bar=False)  # on to the run's own 360 steps
    assert [r.timesteps for r in result.evaluations] == [120, 240, 360]
    meta = json.loads((tmp_path / "model.json").read_text())
    assert [p["status"] for p in meta["parts"]] == ["interrupted", "finished"]


@needs_train
def test_resume_refuses_what_it_cannot_continue(tmp_path):
    folder = tmp_path / "run"
    assert _tiny_run(folder, steps="120").exit_code == 0
    cases = [
        (["--resume", str(folder), "-p", "gamma=0.9"], "drop -p"),
        (["--resume", str(folder), "--algo", "td3", "--seed", "2"], "drop --algo, --seed"),
        (["--resume", str(folder)], "the run is at 120 steps already; pass --steps above 120"),
        (["UR5eReacherGoalSim-v0", "--resume", str(folder)], "that run trains VX300SReacherGoalSim-v0"),
        (["--resume", str(tmp_path)], "no model.json, so not a run folder"),
        ([], "give the ID to train, or --resume RUN_FOLDER"),
    ]
    for args, message in cases:
        result = runner.invoke(app, ["train", *args, "--no-progress"])
        assert result.exit_code == 1 and message in result.output, (args, result.output)
        assert "Traceback" not in result.output
    meta = json.loads((folder / "model.json").read_text())
    (folder / "model.json").write_text(json.dumps({**meta, "replay_buffer_timesteps": 60}))  # an older buffer
    result = runner.invoke(app, ["train", "--resume", str(folder), "--steps", "240"])
    assert result.exit_code == 1 and "replay_buffer.pkl was saved at 60 steps but its model at 120" in result.output
    (folder / "model.json").write_text(json.dumps(meta))
    (folder / "replay_buffer.pkl").unlink()  # as after a hard kill
    result = runner.invoke(app, ["train", "--resume", str(folder), "--steps", "240"])
    assert result.exit_code == 1 and "no replay_buffer.pkl, so the run cannot continue" in result.output


@needs_train
def test_tensorboard_log_gets_the_run_and_its_evaluations(tmp_path):
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    result = _tiny_run(tmp_path / "run", "-p", f"tensorboard_log={tmp_path / 'tb'}")
    assert result.exit_code == 0, result.output
    events = tmp_path / "tb" / "run_1"
    assert list(events.glob("events.out.tfevents.*"))
    accumulator = EventAccumulator(str(events))
    accumulator.Reload()
    rates = accumulator.Scalars("eval/success_rate")
    curve = list(csv.DictReader(open(tmp_path / "run" / "curve.csv")))
    assert [(e.step, e.value) for e in rates] == [(int(r["timesteps"]), float(r["success_rate"])) for r in curve]
    assert "train/actor_loss" in accumulator.Tags()["scalars"]
    assert json.loads((tmp_path / "run" / "model.json").read_text())["tensorboard"] == str(events)


@needs_train
def test_a_run_that_fails_before_its_first_evaluation_leaves_nothing(tmp_path, monkeypatch):
    (tmp_path / "taken").write_text("a file where the TensorBoard folder would go")
    result = _tiny_run(tmp_path / "run", "-p", f"tensorboard_log={tmp_path / 'taken'}")
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert not (tmp_path / "run").exists()

    import envfactory.learn.loop as loop
    from envfactory.learn.trainer import train

    def broken(*args, **kwargs):
        raise RuntimeError("the evaluation env broke")

    monkeypatch.setattr(loop, "evaluate", broken)  # fails at step 120, after TensorBoard began its events
    with pytest.raises(RuntimeError, match="the evaluation env broke"):
        train(
            "VX300SReacherGoalSim-v0",
            tmp_path / "run",
            steps=240,
            eval_every=120,
            eval_episodes=1,
            progress_bar=False,
            overrides=(*TINY[1::2], f"tensorboard_log={tmp_path / 'tb'}"),
        )
    assert not (tmp_path / "run").exists() and not (tmp_path / "tb" / "run_1").exists()


def test_hyperparameters_merge_default_family_and_command_line():
    hyper = load(
        "sac", "UR5eReacherGoalSim-v0", ["gamma=0.9", "policy_kwargs.net_arch=[64, 64]", "her.n_sampled_goal=8"]
    )
    assert hyper.values["gamma"] == 0.9 and hyper.values["policy_kwargs"]["net_arch"] == [64, 64]
    assert hyper.values["her"] == {"n_sampled_goal": 8, "goal_selection_strategy": "future"}  # merged, not replaced
    assert hyper.sources[0].endswith("sac.yaml: default") and hyper.sources[-1].startswith("command line")
    assert "env_kwargs" not in hyper.algorithm_kwargs() and "her" not in hyper.algorithm_kwargs()


def test_family_and_id_blocks_override_the_default(tmp_path, monkeypatch):
    import envfactory.learn.hyperparams as hp

    (tmp_path / "sac.yaml").write_text(
        "default: {gamma: 0.95, batch_size: 256}\nur5e_reach: {gamma: 0.9}\nUR5eReacherGoalSim-v0: {batch_size: 64}\n"
    )
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


def test_floats_read_as_yaml_1_2_writes_them():
    """PyYAML reads `3e-4` as text; a learning rate of '3e-4' used to fail deep inside SB3."""
    assert parse_overrides(["learning_rate=3e-4", "buffer_size=1e6", "name=e5", "net=[1e-3, x]"]) == {
        "learning_rate": 0.0003,
        "buffer_size": 1_000_000.0,
        "name": "e5",
        "net": [0.001, "x"],
    }


@needs_train
@pytest.mark.parametrize(
    "override, message",
    [
        ("learning_rate=fast", "learning_rate must be a number, got 'fast'"),
        ("gamma=[0.9]", "gamma must be a number, got [0.9]"),
        ("batch_size=12.5", "batch_size must be a whole number, got 12.5"),
        # in range for what the algorithm can learn with: SB3 runs each of these, or fails in its first update
        ("batch_size=0", "batch_size=0 must be a whole number of at least 1"),
        ("gamma=1.5", "gamma=1.5 must be a discount in (0, 1]"),
        ("buffer_size=-1", "buffer_size=-1 must be a whole number of at least 1"),
        ("learning_rate=-0.001", "learning_rate=-0.001 must be a finite number above 0"),
        ("learning_rate=.nan", "learning_rate=nan must be a finite number above 0"),
        ("n_timesteps=-5", "n_timesteps=-5 must be a whole number of steps, at least 1"),
        ("ent_coef=autom", "ent_coef='autom' must be 'auto', 'auto_START' or a finite number"),
    ],
)
def test_hyperparameters_of_the_wrong_type_or_range_fail_before_a_run_folder_exists(tmp_path, override, message):
    result = runner.invoke(app, ["train", "VX300SReacherGoalSim-v0", "-p", override, "--out", str(tmp_path / "run")])
    assert result.exit_code == 1
    assert message in result.output and "command line" in result.output
    assert not (tmp_path / "run").exists()


@needs_train
def test_her_learning_starts_within_the_first_episode_is_refused(tmp_path):
    result = runner.invoke(
        app, ["train", "VX300SReacherGoalSim-v0", "-p", "learning_starts=50", "--out", str(tmp_path)]
    )
    assert result.exit_code == 1
    assert "learning_starts=50 must exceed the episode limit of VX300SReacherGoalSim-v0 (100 steps)" in result.output


@needs_train
def test_unknown_hyperparameter_fails_before_training(tmp_path):
    result = runner.invoke(app, ["train", "VX300SReacherGoalSim-v0", "-p", "learning_rat=0.1", "--out", str(tmp_path)])
    assert result.exit_code == 1
    assert "unknown hyperparameter(s) learning_rat" in result.output and "command line" in result.output
    assert not (tmp_path / "model.zip").exists()


@needs_train
def test_a_sweep_over_an_unknown_name_is_refused_before_any_trial(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(
        app, ["train", "VX300SReacherGoalSim-v0", "--seeds", "0", "--sweep", "learning_rat=0.1,0.2", "--no-progress"]
    )
    assert result.exit_code == 1 and "unknown hyperparameter(s) learning_rat" in " ".join(result.output.split())
    assert not (tmp_path / "runs").exists()


@pytest.fixture
def user_reach(tmp_path):
    """A user folder with a copy of the UR5e Reach family (its Sim ID renamed), registered for the test."""
    from test_silent_mistakes import user_folder

    from envfactory.factory import register_specs, unregister_folder

    folder = user_folder(tmp_path, "ur5e_reach")
    added, problems = register_specs(folder)
    assert added and not problems, problems
    yield folder
    unregister_folder(folder)


def test_a_misspelled_block_in_a_user_settings_file_is_named_with_its_line(user_reach):
    (user_reach / "specs" / "train").mkdir()
    (user_reach / "specs" / "train" / "sac.yaml").write_text("ur5e_rech:\n  gamma: 0.9\n")
    with pytest.raises(
        HyperparameterError,
        match=r"sac.yaml:1: block 'ur5e_rech' names no family or env ID \(did you mean 'ur5e_reach'\?\)",
    ):
        load("sac", "MyUR5eReacherSim-v0")


def test_a_settings_folder_that_is_never_read_is_named(user_reach):
    train = user_reach / "specs" / "train"
    (user_reach / "train").mkdir()
    (user_reach / "train" / "sac.yaml").write_text("default:\n  gamma: 0.9\n")
    with pytest.raises(HyperparameterError, match=r"train: never read \(training settings go beside the family"):
        load("sac", "MyUR5eReacherSim-v0")
    (user_reach / "train").rename(train)
    (train / "sac.yaml").rename(train / "SAC.yml")
    with pytest.raises(HyperparameterError, match=r"SAC.yml: never read \(a file is named for its algorithm"):
        load("sac", "MyUR5eReacherSim-v0")
    (train / "SAC.yml").rename(train / "sac.yaml")
    assert load("sac", "MyUR5eReacherSim-v0").values["gamma"] == 0.9


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
    result = runner.invoke(
        app, ["collect", "UR5eReacherGoalSim-v0", "--episodes", "4", "--data-path", str(tmp_path), *kwargs]
    )
    assert result.exit_code == 0, result.output
    dataset = minari.load_dataset("envfactory/ur5ereachergoalsim/expert-v0")
    assert dataset.total_episodes == 4
    env = dataset.recover_environment()
    try:
        for episode in dataset.iterate_episodes():
            obs = episode.observations
            assert len(obs["observation"]) == len(episode.actions) + 1
            assert all(env.action_space.contains(a) for a in episode.actions)
            # the original suite's sparse reward, recomputed from the recorded goals: 0 within 2 cm, else -1
            distance = np.linalg.norm(obs["achieved_goal"][1:] - obs["desired_goal"][1:], axis=1)
            assert np.array_equal(episode.rewards, np.where(distance < 0.02, 0.0, -1.0))
            assert episode.terminations[-1] and distance[-1] < 0.02  # the expert reaches every goal
            # success per step, judged against the recorded goals (2 cm tolerance)
            assert np.array_equal(episode.infos["is_success"][1:], distance < 0.02)
    finally:
        env.close()

    again = runner.invoke(app, ["collect", "UR5eReacherGoalSim-v0", "--episodes", "1", "--data-path", str(tmp_path)])
    assert again.exit_code == 1 and "already exists" in again.output and "--overwrite" in again.output


@needs_minari
def test_collect_warns_of_nothing_and_records_what_it_is_given(tmp_path, monkeypatch):
    """Minari warned four times per dataset (no author, e-mail, code link, evaluation env): collect now gives the
    code link and the evaluation env, and the author and e-mail when the user does (--author, --author-email)."""
    import warnings

    import minari

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    command = ["collect", "UR5eReacherGoalSim-v0", "--episodes", "1", "--data-path", str(tmp_path)]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        plain = runner.invoke(app, command)
        signed = runner.invoke(
            app, [*command, "--dataset-id", "test/signed-v0", "--author", "Ada", "--author-email", "ada@example.org"]
        )
    assert plain.exit_code == 0 and signed.exit_code == 0, plain.output + signed.output
    assert [f"{w.category.__name__}: {w.message}" for w in caught] == []
    unsigned = minari.load_dataset("envfactory/ur5ereachergoalsim/expert-v0").storage.metadata
    assert "author" not in unsigned and "author_email" not in unsigned  # never guessed
    metadata = minari.load_dataset("test/signed-v0").storage.metadata
    assert metadata["author"] == {"Ada"} and metadata["author_email"] == {"ada@example.org"}
    assert metadata["code_permalink"].startswith("envfactory ")
    assert metadata["eval_env_spec"] == metadata["env_spec"]  # evaluated where it was collected


@needs_train
def test_a_model_trained_in_simulation_runs_on_the_real_id_without_its_simulation_only_kwargs(tmp_path, twin):
    """A model trained on MuJoCo with randomization runs on the Real ID as it is: `run` leaves out the kwargs only
    a simulator has, says which, and keeps the rest (the action and observation settings it was trained with)."""
    assert _tiny_run(tmp_path / "run", "-k", "engine=mujoco", "-k", "randomize=true").exit_code == 0
    stand_in = twin("vx300s", "reach")
    result = runner.invoke(
        app,
        [
            "run",
            "VX300SReacherGoalReal-v0",
            "--policy",
            str(tmp_path / "run" / "model.zip"),
            "-n",
            "1",
            "--allow-real-robot-motion",
            "-k",
            f"rosbridge_port={stand_in.port}",
            "-k",
            "max_episode_steps=2",
        ],
    )
    assert result.exit_code == 0, result.output
    assert "simulation-only kwargs are left out: engine='mujoco', randomize=True" in " ".join(result.output.split())
    assert "success rate" in result.output
    assert stand_in.received  # it drove the twin
    sent = len(stand_in.received)
    result = runner.invoke(
        app,
        [
            "evaluate",
            "VX300SReacherGoalReal-v0",
            "--policy",
            str(tmp_path / "run" / "model.zip"),
            "-n",
            "1",
            "--allow-real-robot-motion",
            "-k",
            f"rosbridge_port={stand_in.port}",
            "-k",
            "max_episode_steps=2",
            "--no-progress",
        ],
    )
    assert result.exit_code == 0, result.output
    assert "simulation-only kwargs are left out: engine='mujoco', randomize=True" in " ".join(result.output.split())
    assert "over 1 episodes" in result.output
    assert len(stand_in.received) > sent  # evaluate drove it too


@needs_train
def test_a_run_of_a_user_id_remembers_its_spec_folder_for_resume_and_run(user_reach, tmp_path):
    """A later process (here: the folder unregistered again) resumes the run and replays its model without
    being given --specs: the run folder records where its ID is declared."""
    from envfactory.factory import unregister_folder

    run = tmp_path / "run"
    common = ["--eval-every", "120", "--eval-episodes", "1", "--no-progress"]
    result = runner.invoke(
        app, ["train", "MyUR5eReacherSim-v0", "--steps", "120", "--out", str(run), *common, *TINY[:6]]
    )
    assert result.exit_code == 0, result.output
    assert json.loads((run / "model.json").read_text())["spec_folder"] == str(user_reach)
    unregister_folder(user_reach)
    resumed = runner.invoke(app, ["train", "--resume", str(run), "--steps", "240", "--no-progress"])
    assert resumed.exit_code == 0, resumed.output
    unregister_folder(user_reach)
    replayed = runner.invoke(app, ["run", "MyUR5eReacherSim-v0", "-n", "1", "--policy", str(run / "model.zip")])
    assert replayed.exit_code == 0, replayed.output


@needs_train
def test_the_best_evaluation_keeps_its_model_and_statistics_across_a_resume(tmp_path, monkeypatch):
    """A curve that swings keeps its best policy in best/: the evaluations' success rates are scripted here (the
    rule under test is which model is kept, not how well it acts), 0.2, 0.6, 0.6 and, after a resume, 0.4 and
    0.8. The earliest of equal evaluations stays; a later, better one replaces it; each kept model is the one the
    run had at that evaluation (its own step count), with its statistics, and replays through --policy."""
    from stable_baselines3.common.save_util import load_from_zip_file

    import envfactory.learn.loop as loop

    scripted = iter([0.2, 0.6, 0.6, 0.4, 0.8])
    monkeypatch.setattr(loop, "evaluate", lambda env, policy, episodes: (next(scripted), -1.0, 1.0))
    folder = tmp_path / "run"
    first = _tiny_run(folder, "-p", "normalize=true", steps="360")
    assert first.exit_code == 0, first.output
    best = folder / "best"
    assert json.loads((best / "model.json").read_text())["best"] == {"timesteps": 240, "success_rate": 0.6}
    assert load_from_zip_file(best / "model.zip")[0]["num_timesteps"] == 240
    assert (best / "vecnormalize.pkl").is_file()
    assert json.loads((folder / "model.json").read_text())["best"] == {"timesteps": 240, "success_rate": 0.6}

    again = runner.invoke(app, ["train", "--resume", str(folder), "--steps", "600", "--no-progress"])
    assert again.exit_code == 0, again.output
    assert json.loads((best / "model.json").read_text())["best"] == {"timesteps": 600, "success_rate": 0.8}
    assert load_from_zip_file(best / "model.zip")[0]["num_timesteps"] == 600

    replay = runner.invoke(app, ["evaluate", "VX300SReacherGoalSim-v0", "--policy", str(best / "model.zip"), "-n", "1"])
    assert replay.exit_code == 0, replay.output
