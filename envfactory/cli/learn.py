"""Commands that learn from the envs: train (SAC, TD3, TQC; HER on goal envs; from demonstrations; resumed) and
collect (expert datasets)."""

from __future__ import annotations

from contextlib import nullcontext
from functools import partial
from pathlib import Path
from typing import List, Optional

import typer

from envfactory.cli.common import KWARG_HELP, command, console, errors, fail, known_id, make_kwargs, override_option
from envfactory.cli.evaluate import (
    SEEDS_HELP,
    SWEEP_HELP,
    address_option,
    cluster_module,
    cluster_size,
    parse_seeds,
    simulated_only,
    train_trials,
    workers_option,
)
from envfactory.learn import extra
from envfactory.learn.demo_replay import DemonstrationError
from envfactory.learn.demonstrations import collect as run_collection
from envfactory.learn.demonstrations import record as record_here
from envfactory.learn.extra import MissingExtra, require
from envfactory.learn.hyperparams import HyperparameterError
from envfactory.learn.models import checked_hyperparameters
from envfactory.learn.runs import RunFolderError, RunRecord, fresh_folder
from envfactory.learn.trainer import BUFFER_FILE, CSV_FILE, META_FILE, MODEL_FILE, PNG_FILE, WALL_PNG_FILE
from envfactory.learn.trainer import resume as resume_training
from envfactory.learn.trainer import train as run_training


def _require(modules: dict, what: str) -> None:
    try:
        require(modules, what)
    except MissingExtra as exc:
        fail(str(exc))


@command()
def train(
    env_id: Optional[str] = typer.Argument(None, help="The ID to train (with --resume: the run's own, if given)"),
    algo: Optional[str] = typer.Option(None, "--algo", "-a", help="sac, td3 or tqc (default: sac)"),
    steps: Optional[int] = typer.Option(
        None,
        "--steps",
        "-n",
        min=1,
        help="Environment steps in all (default: n_timesteps of the hyperparameters; with --resume, the run's own)",
    ),
    seed: Optional[int] = typer.Option(None, help="Seed of the model and of the training env (default: 0)"),
    out: Optional[Path] = typer.Option(
        None,
        "--out",
        help="Run folder (default: runs/ID-ALGO-seedN); one "
        "holding an earlier run is never overwritten: the "
        "run goes to NAME-2, NAME-3...",
    ),
    hyperparameter: List[str] = typer.Option(
        None, "--hyperparameter", "-p", help="Override as name=value (dotted names nest), repeatable"
    ),
    kwarg: List[str] = typer.Option(None, "--kwarg", "-k", help=KWARG_HELP + " (over the hyperparameters' env_kwargs)"),
    override: List[str] = override_option(),
    eval_every: Optional[int] = typer.Option(None, min=1, help="Evaluate every this many steps"),
    eval_episodes: Optional[int] = typer.Option(None, min=1, help="Episodes per evaluation"),
    demos: Optional[str] = typer.Option(
        None,
        "--demos",
        help="Learn from demonstrations: a Minari dataset (ID, or "
        "its folder) written by `envfactory collect` with the "
        "same kwargs; they seed the replay buffer and the "
        "behaviour-cloning term (the `demos` block of the "
        "hyperparameters)",
    ),
    resume: Optional[Path] = typer.Option(
        None,
        "--resume",
        help="Continue the run in this folder with its model, replay buffer and settings; --steps sets the new total",
    ),
    seeds: Optional[str] = typer.Option(None, "--seeds", help=SEEDS_HELP),
    sweep: List[str] = typer.Option(None, "--sweep", help=SWEEP_HELP),
    workers: Optional[int] = workers_option(),
    address: Optional[str] = address_option(),
    progress: bool = typer.Option(True, "--progress/--no-progress", help="Show a progress bar"),
):
    """Train SAC, TD3 or TQC on an ID (HER on goal envs), optionally from demonstrations; save the model, the
    replay buffer and the success-rate curve. --resume continues a stopped run. --seeds (and --sweep) train
    several runs, with --workers as Ray Tune trials."""

    _require({**extra.TRAIN_MODULES, **extra.PLOT_MODULES}, "envfactory train")
    if seeds is not None or sweep:
        if resume is not None or (seeds is not None and seed is not None) or env_id is None:
            fail("--seeds and --sweep start new runs of an ID: give the ID, and drop --resume and --seed")
        known_id(env_id)
        train_trials(
            env_id,
            algo or "sac",
            parse_seeds(seeds) if seeds is not None else [seed or 0],
            sweep or [],
            out,
            tuple(hyperparameter or ()),
            steps,
            make_kwargs(kwarg, override),
            eval_every,
            eval_episodes,
            demos,
            workers,
            address,
            progress,
        )
        return
    if workers is not None or address is not None:
        fail("--workers and --address spread several runs: give --seeds (or --sweep) too")

    def report(row) -> None:
        console.print(
            f"step {row.timesteps:>7}: success {row.success_rate:6.1%}  return {row.mean_return:8.2f}  "
            f"length {row.mean_length:5.1f}  ({row.episodes} episodes, {row.wall_s:.0f} s)"
        )

    if resume is not None:
        folder = _resumable(
            resume,
            env_id,
            {
                "--algo": algo,
                "--seed": seed,
                "--out": out,
                "-p": hyperparameter,
                "-k": kwarg,
                "-o": override,
                "--eval-every": eval_every,
                "--eval-episodes": eval_episodes,
                "--demos": demos,
            },
        )
        console.print(f"resuming {folder}")
        start = partial(resume_training, folder, steps=steps, progress_bar=progress, on_evaluation=report)
    else:
        if env_id is None:
            fail("give the ID to train, or --resume RUN_FOLDER")
        known_id(env_id)
        algo, seed = algo or "sac", 0 if seed is None else seed
        try:
            checked_hyperparameters(algo, env_id, hyperparameter or ())  # bad names or values: before anything is built
        except HyperparameterError as exc:
            fail(str(exc))
        asked = out or Path("runs") / f"{env_id}-{algo.lower()}-seed{seed}"
        if asked.exists() and not asked.is_dir():
            fail(f"{asked}: is a file; give a folder for the run")
        folder = fresh_folder(asked)
        if folder != asked:
            console.print(
                f"{asked} holds an earlier run, which is never overwritten: this run goes to {folder} "
                f"(`envfactory train --resume {asked}` would continue that one)"
            )
        start = partial(
            run_training,
            env_id,
            folder,
            algo=algo,
            seed=seed,
            steps=steps,
            overrides=tuple(hyperparameter or ()),
            env_kwargs=make_kwargs(kwarg, override),
            eval_every=eval_every,
            eval_episodes=eval_episodes,
            demos=demos,
            progress_bar=progress,
            on_evaluation=report,
        )
    try:
        result = start()
    except (HyperparameterError, RunFolderError, DemonstrationError) as exc:
        fail(str(exc))
    except KeyboardInterrupt:
        _stopped(folder)
    env_id = RunRecord.read(folder).data["env_id"]
    console.print(f"model: {folder / MODEL_FILE} (its settings and parts: {folder / META_FILE})")
    console.print(
        f"replay buffer: {folder / BUFFER_FILE} ({result.replay_buffer_bytes / 1e6:.0f} MB; "
        f"`envfactory train --resume {folder} --steps N` continues the run)"
    )
    console.print(f"learning curve: {folder / CSV_FILE}, {folder / PNG_FILE}, {folder / WALL_PNG_FILE}")
    if result.evaluations:
        console.print(
            f"final success rate: {result.evaluations[-1].success_rate:.0%}; replay it with "
            f"`envfactory run {env_id} --policy {folder / MODEL_FILE}`"
        )


def _resumable(folder: Path, env_id: str | None, settings: dict) -> Path:
    """The run folder to resume, refused with the reason before anything is built."""
    given = [name for name, value in settings.items() if value not in (None, [], ())]
    if given:
        fail(
            f"--resume continues the run with the settings it was started with ({folder / META_FILE}); "
            f"drop {', '.join(given)}"
        )
    try:
        record = RunRecord.read(folder)
    except RunFolderError as exc:
        fail(str(exc))
    if env_id is not None and env_id != record.data["env_id"]:
        fail(f"--resume {folder}: that run trains {record.data['env_id']}, not {env_id}")
    return folder


def _stopped(folder: Path) -> None:
    """Ctrl-C or SIGTERM: the trainer saved where the run stands; say how to go on."""
    try:
        record = RunRecord.read(folder)
    except RunFolderError:
        errors.print(f"stopped before {folder} held a run")
        raise typer.Exit(130)
    errors.print(
        f"stopped at step {record.data.get('timesteps', 0)}: model and replay buffer saved in {folder}; "
        f"continue with `envfactory train --resume {folder}`"
    )
    raise typer.Exit(130)


@command()
def collect(
    env_id: str,
    episodes: int = typer.Option(100, "--episodes", "-n", min=1),
    dataset_id: Optional[str] = typer.Option(
        None, "--dataset-id", help="Minari dataset ID (default: envfactory/<id>/expert-v0)"
    ),
    seed: int = typer.Option(0, help="Seed of the first episode; episode i uses seed + i"),
    data_path: Optional[Path] = typer.Option(
        None, "--data-path", help="Datasets folder (default: Minari's, MINARI_DATASETS_PATH or ~/.minari/datasets)"
    ),
    overwrite: bool = typer.Option(False, "--overwrite", help="Replace a dataset of the same ID"),
    kwarg: List[str] = typer.Option(None, "--kwarg", "-k", help=KWARG_HELP),
    override: List[str] = override_option(),
    author: Optional[str] = typer.Option(
        None, "--author", help="Recorded in the dataset's metadata (left out if not given)"
    ),
    author_email: Optional[str] = typer.Option(
        None, "--author-email", help="Recorded in the dataset's metadata (left out if not given)"
    ),
    action_noise: float = typer.Option(
        0.0,
        "--action-noise",
        min=0.0,
        max=1.0,
        help="Gaussian noise added to each expert action, std as a fraction of the action's half-range; the "
        "noisy action is recorded (the expert then shows how it recovers: noise injection, DART)",
    ),
    workers: Optional[int] = workers_option(),
    address: Optional[str] = address_option(),
):
    """Run the scripted expert and write its episodes as a Minari dataset (load with minari.load_dataset).

    Each episode runs until the env ends it (terminated or truncated), not at its first success, so a learner
    sees what follows success too. Recover the env in any process with
    envfactory.learn.demonstrations.load_env(dataset), which also registers a user folder's IDs. With
    --workers the episodes run as Ray tasks; the dataset is the same."""

    known_id(env_id)
    _require(extra.COLLECT_MODULES, "envfactory collect")

    kwargs = make_kwargs(kwarg, override)
    simulated_only(env_id, "collect")
    size = cluster_size(workers, address)
    pool = None if size is None else cluster_module("pool", "collect --workers/--address")
    try:
        with pool.connected(size, address) if pool else nullcontext():
            recorder = pool.recorder(pool.cluster_cpus(size)) if pool else record_here
            result = run_collection(
                env_id,
                episodes,
                dataset_id=dataset_id,
                seed=seed,
                env_kwargs=kwargs,
                data_path=data_path,
                overwrite=overwrite,
                author=author,
                author_email=author_email,
                recorder=recorder,
                action_noise=action_noise,
            )
    except FileExistsError as exc:
        fail(str(exc))
    console.print(
        f"dataset {result.dataset_id}: {result.episodes} episodes run to the env's end, {result.steps} "
        f"steps, {result.successes} reach the goal; written to {result.path}"
    )
    console.print(
        f"load it with: import minari; minari.load_dataset({result.dataset_id!r})"
        + (f" (with MINARI_DATASETS_PATH={data_path.resolve()})" if data_path else "")
        + "; its env: envfactory.learn.demonstrations.load_env(dataset)"
    )
