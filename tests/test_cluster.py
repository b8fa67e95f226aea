"""collect, evaluate and train on a local Ray instance (2 CPUs, started once for the module): the same episodes
as one process, a killed worker costs no episode and adds no partial one, user spec folders and trained models
reach the workers by value, trials write their folders and a summary, and RLlib trains on an ID by name.

Skipped, with the reason, where the [ray] extra is not installed; tests/test_cluster_local.py covers the rest."""

from __future__ import annotations

import csv
import os
import sys
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from typer.testing import CliRunner

from envfactory.learn import extra
from envfactory.registration import registry

ray = pytest.importorskip("ray", reason="the [ray] extra is not installed (pip install 'envfactory[ray]')")

from test_robot_folder import _robot_folder  # noqa: E402

from envfactory.cli.app import app  # noqa: E402
from envfactory.cluster import pool, trials  # noqa: E402
from envfactory.cluster.work import SeedEvaluation, ShippedFolders, run_here  # noqa: E402
from envfactory.factory import unregister_folder  # noqa: E402

runner = CliRunner()
REACH, GOAL_REACH, USER_ID = "UR5eReacherSim-v0", "UR5eReacherGoalSim-v0", "MyArmReach-v0"
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
needs_train = pytest.mark.skipif(
    bool(extra.missing({**extra.TRAIN_MODULES, **extra.PLOT_MODULES, **extra.COLLECT_MODULES})),
    reason="the [train] extra is not installed (pip install -e '.[train]')",
)

# the crash test's work class lives here: the workers get it by value, as they cannot import a test module
ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])


@pytest.fixture(scope="module", autouse=True)
def local_ray():
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


@pytest.fixture(scope="module")
def user_folder(tmp_path_factory):
    """A user robot's spec folder, passed with --specs or registered in this process only: the workers get
    it with the job, not from a variable or a recorded folder."""
    folder = _robot_folder(tmp_path_factory.mktemp("user"), packages="  packages: {arm_description: ..}\n")
    yield folder
    unregister_folder(folder)


def _ok(*args) -> str:
    result = runner.invoke(app, [str(arg) for arg in args])
    assert result.exit_code == 0, result.output
    return result.output


def _rows(path: Path) -> list[dict]:
    return list(csv.DictReader(open(path)))


def test_evaluate_on_two_workers_gives_the_episodes_of_one_process(tmp_path, monkeypatch, user_folder):
    monkeypatch.chdir(user_folder.parent)  # the folder is given relative to the head's working folder
    here, spread = tmp_path / "here.csv", tmp_path / "spread.csv"
    common = [
        "evaluate",
        REACH,
        "UR5ePushGoalSim-v0",
        USER_ID,
        "-n",
        "5",
        "--seed",
        "7",
        "--specs",
        user_folder.name,
        "--no-progress",
    ]
    try:
        _ok(*common, "--csv", here)
        _ok(*common, "--csv", spread, "--workers", "2")
    finally:
        unregister_folder(user_folder.name)  # registered by its relative path: forget it while that holds
    assert _rows(spread) == _rows(here) and len(_rows(here)) == 15


@needs_train
def test_collect_on_two_workers_writes_the_dataset_of_one_process(tmp_path):
    import h5py

    for name, more in (("here", []), ("spread", ["--workers", "2"])):
        _ok("collect", GOAL_REACH, "-n", "6", "--seed", "3", "--data-path", tmp_path / name, *more)
    files = [next((tmp_path / name).rglob("main_data.hdf5")) for name in ("here", "spread")]
    contents = []
    for path in files:
        found = {}
        with h5py.File(path) as data:
            data.visititems(
                lambda key, item: found.__setitem__(key, item[()]) if isinstance(item, h5py.Dataset) else None
            )
            seeds = [int(data[f"episode_{i}"].attrs["seed"]) for i in range(6)]
        contents.append(found)
        assert seeds == list(range(3, 9))
    assert contents[0].keys() == contents[1].keys() and len(contents[0]) > 6
    assert all(np.array_equal(contents[0][key], contents[1][key]) for key in contents[0])


@dataclass(frozen=True)
class CrashingOnce(SeedEvaluation):
    """SeedEvaluation whose worker process dies after the first episode of the range holding `seed`, the first
    time only (the marker file remembers): a worker lost mid-range."""

    marker: str = ""
    seed: int = 0

    def run(self, seeds, on_episode):
        def die_once(result):
            if result.seed == self.seed and not os.path.exists(self.marker):
                Path(self.marker).write_text(str(os.getpid()))
                os._exit(1)

        return super().run(seeds, die_once)


def test_a_killed_worker_costs_no_episode_and_adds_no_partial_one(tmp_path):
    marker = tmp_path / "died"
    seeds = range(0, 12)
    work = CrashingOnce(REACH, {}, ShippedFolders(), marker=str(marker), seed=4)
    spread = pool.run_episodes_on_ray([work], seeds, workers=2, progress=False)[0]
    assert marker.is_file() and int(marker.read_text()) != os.getpid()  # a worker died, not this process
    reference = run_here(SeedEvaluation(REACH), seeds)
    assert spread == reference  # every seed once, whole, in order: the range that died ran again


def test_an_error_in_the_work_names_the_id_and_the_seeds():
    with pytest.raises(
        pool.ClusterError,
        match=r"(?s)UR5eReacherSim-v0 seeds \d\.\.\d: SpecError: .*unknown kwarg "
        "'no_such_kwarg'",
    ):
        pool.run_episodes_on_ray([SeedEvaluation(REACH, {"no_such_kwarg": 1})], range(0, 2), workers=2, progress=False)


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """Two tiny SAC trials of the Reach goal env as Ray Tune trials on two workers: their group folder."""
    group = tmp_path_factory.mktemp("trials") / "group"
    _ok(
        "train",
        GOAL_REACH,
        "--seeds",
        "0,1",
        "--steps",
        "240",
        "--eval-every",
        "120",
        "--eval-episodes",
        "2",
        "--out",
        group,
        "--workers",
        "2",
        "--no-progress",
        *TINY,
    )
    return group


@needs_train
def test_trials_write_their_run_folders_a_summary_and_the_curves(trained):
    rows = _rows(trained / trials.SUMMARY_FILE)
    assert [(r["trial"], r["error"]) for r in rows] == [("seed0", ""), ("seed1", "")]
    assert all(int(r["timesteps"]) == 240 for r in rows)
    for seed in (0, 1):
        curve = _rows(trained / f"seed{seed}" / "curve.csv")
        assert [int(r["timesteps"]) for r in curve] == [120, 240]
        assert (trained / f"seed{seed}" / "model.zip").is_file()
    for name in (trials.CURVES_FILE, trials.WALL_CURVES_FILE):
        assert (trained / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # each ran as a Ray Tune trial and reported its evaluations to Tune as they happened (Tune's own record)
    for seed in (0, 1):
        reported = _rows(trained / "tune" / "trials" / f"seed{seed}" / "progress.csv")
        assert [(int(r["timesteps"]), float(r["success_rate"])) for r in reported] == [
            (int(r["timesteps"]), float(r["success_rate"])) for r in _rows(trained / f"seed{seed}" / "curve.csv")
        ]


@needs_train
def test_a_failed_ray_trial_names_its_cause_in_the_summary(tmp_path):
    """Ray wraps what a trial raised in a task error whose first line names the task and its process, in
    terminal colours: the summary row gives the trial's own error instead."""
    group = tmp_path / "group"
    result = runner.invoke(
        app,
        ["train", GOAL_REACH, "--seeds", "0", "--sweep", "policy_kwargs.no_such_option=1", "--out", str(group)]
        + ["--workers", "1"]
        + ["--no-progress"],
    )
    assert result.exit_code == 1, result.output
    (row,) = _rows(group / trials.SUMMARY_FILE)
    assert row["error"].startswith("TypeError: ") and "no_such_option" in row["error"], row["error"]
    assert "\x1b" not in row["error"] and "ray::" not in row["error"]


@needs_train
def test_a_trained_model_acts_alike_on_the_workers(trained, tmp_path):
    model = trained / "seed1" / "model.zip"
    here, spread = tmp_path / "here.csv", tmp_path / "spread.csv"
    common = ["evaluate", GOAL_REACH, "--policy", model, "-n", "4", "--no-progress"]
    _ok(*common, "--csv", here)
    _ok(*common, "--csv", spread, "--workers", "2")
    assert _rows(spread) == _rows(here) and len(_rows(here)) == 4


def test_rllib_trains_a_few_iterations_on_a_goal_id_by_name():
    """PPO on two env runners, on a Reach goal ID flattened for RLlib's default model; the kwargs in env_config
    reach the runners' envs."""
    from ray.rllib.algorithms.ppo import PPOConfig

    from envfactory.cluster import rllib

    assert GOAL_REACH in rllib.register([GOAL_REACH])
    config = (
        PPOConfig()
        .environment(GOAL_REACH, env_config={"ee_action_type": True, "flatten_observation": True})
        .env_runners(num_env_runners=2, rollout_fragment_length=50)
        .training(train_batch_size_per_learner=200, minibatch_size=100, num_epochs=1)
        .rl_module(model_config={"fcnet_hiddens": [16, 16]})
    )
    algo = config.build_algo()
    try:
        sampled = [algo.train()["env_runners"]["num_env_steps_sampled_lifetime"] for _ in range(2)]
        spaces = algo.env_runner_group.foreach_env_runner(
            lambda runner: (runner.env.single_action_space.shape, runner.env.single_observation_space.shape),
            local_env_runner=False,
        )
    finally:
        algo.stop()
    assert sampled[0] >= 200 and sampled[1] >= sampled[0] + 200
    made = gym.make(GOAL_REACH, ee_action_type=True)
    flat = gym.wrappers.FlattenObservation(made)
    expected = (made.action_space.shape, flat.observation_space.shape)
    made.close()
    # EE mode has fewer action rows than joint mode: the kwargs reached both runners
    assert spaces == [expected, expected] and made.action_space.shape != gym.spec(GOAL_REACH).make().action_space.shape


def test_rllib_runs_the_native_vector_env_in_each_runner():
    """RLlib's vector-entry-point mode: each runner asks the creator for its envs at once and holds one native
    vector env, N envs in its process."""
    from ray.rllib.algorithms.ppo import PPOConfig

    from envfactory.cluster import rllib

    rllib.register([GOAL_REACH])
    config = (
        PPOConfig()
        .environment(GOAL_REACH, env_config={"ee_action_type": True, "flatten_observation": True})
        .env_runners(
            num_env_runners=1,
            num_envs_per_env_runner=3,
            gym_env_vectorize_mode=gym.VectorizeMode.VECTOR_ENTRY_POINT,
            rollout_fragment_length=40,
        )
        .training(train_batch_size_per_learner=120, minibatch_size=60, num_epochs=1)
        .rl_module(model_config={"fcnet_hiddens": [16, 16]})
    )
    algo = config.build_algo()
    try:
        sampled = algo.train()["env_runners"]["num_env_steps_sampled_lifetime"]
        held = algo.env_runner_group.foreach_env_runner(
            lambda runner: (type(runner.env.unwrapped).__name__, len(runner.env.unwrapped.envs)),
            local_env_runner=False,
        )
    finally:
        algo.stop()
    assert sampled >= 120
    assert held == [("RobotVectorEnv", 3)]


def test_the_creator_refuses_a_flatten_option_that_is_no_switch():
    from envfactory.cluster import rllib

    with pytest.raises(ValueError, match="flatten_observation='yes' must be true or false"):
        rllib.EnvCreator(GOAL_REACH, ShippedFolders.for_ids([GOAL_REACH]))({"flatten_observation": "yes"})


def test_an_rllib_env_creator_makes_a_user_id_in_a_worker(user_folder):
    from envfactory.cluster import rllib

    registry.register_folder(user_folder)
    assert rllib.register([USER_ID]) == [USER_ID]
    creator = rllib.EnvCreator(USER_ID, ShippedFolders.for_ids([USER_ID]))

    @ray.remote
    def make_and_reset(make):
        env = make({"num_envs": 1})  # RLlib's vector entry point: a native vector env of one
        observation, _ = env.reset(seed=0)
        env.close()
        return env.spec.id, observation[0].tolist()

    env = creator({})
    try:
        expected = env.reset(seed=0)[0].tolist()
    finally:
        env.close()
    assert ray.get(make_and_reset.remote(creator)) == (USER_ID, expected)
