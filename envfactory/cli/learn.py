"""Commands that learn from the envs: train (SAC, TD3, TQC; HER on goal envs) and collect (expert datasets)."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from envfactory import registry
from envfactory.cli.app import KWARG_HELP, _fail, _known, _parse_kwargs, command, console
from envfactory.learn import extra
from envfactory.learn.demonstrations import collect as run_collection
from envfactory.learn.extra import MissingExtra, require
from envfactory.learn.hyperparams import HyperparameterError, load
from envfactory.learn.trainer import CSV_FILE, META_FILE, MODEL_FILE, PNG_FILE
from envfactory.learn.trainer import train as run_training


def _require(modules: dict, what: str) -> None:
    try:
        require(modules, what)
    except MissingExtra as exc:
        _fail(str(exc))


@command()
def train(
    env_id: str,
    algo: str = typer.Option("sac", "--algo", "-a", help="sac, td3 or tqc"),
    steps: Optional[int] = typer.Option(None, "--steps", "-n", min=1, help="Environment steps (default: n_timesteps "
                                                                            "of the hyperparameters)"),
    seed: int = typer.Option(0, help="Seed of the model and of the training env"),
    out: Optional[Path] = typer.Option(None, "--out", "-o", help="Run folder (default: runs/ID-ALGO-seedN)"),
    hyperparameter: List[str] = typer.Option(None, "--hyperparameter", "-p",
                                             help="Override as name=value (dotted names nest), repeatable"),
    kwarg: List[str] = typer.Option(None, "--kwarg", "-k", help=KWARG_HELP + " (over the hyperparameters' "
                                                                             "env_kwargs)"),
    eval_every: Optional[int] = typer.Option(None, min=1, help="Evaluate every this many steps"),
    eval_episodes: Optional[int] = typer.Option(None, min=1, help="Episodes per evaluation"),
    progress: bool = typer.Option(True, "--progress/--no-progress", help="Show a progress bar"),
):
    """Train SAC, TD3 or TQC on an ID (HER on goal envs); save the model and the success-rate curve."""

    _known(env_id)
    _require({**extra.TRAIN_MODULES, **extra.PLOT_MODULES}, "envfactory train")

    try:
        load(algo, env_id, hyperparameter or ())  # bad names or values fail before anything is built
    except HyperparameterError as exc:
        _fail(str(exc))
    folder = out or Path("runs") / f"{env_id}-{algo.lower()}-seed{seed}"
    if folder.exists() and not folder.is_dir():
        _fail(f"{folder}: is a file; give a folder for the run")

    def report(row) -> None:
        console.print(f"step {row.timesteps:>7}: success {row.success_rate:6.1%}  return {row.mean_return:8.2f}  "
                      f"length {row.mean_length:5.1f}  ({row.episodes} episodes, {row.wall_s:.0f} s)")

    try:
        result = run_training(env_id, folder, algo=algo, seed=seed, steps=steps, overrides=tuple(hyperparameter or ()),
                              env_kwargs=_parse_kwargs(kwarg), eval_every=eval_every, eval_episodes=eval_episodes,
                              progress_bar=progress, on_evaluation=report)
    except HyperparameterError as exc:
        _fail(str(exc))
    console.print(f"model: {folder / MODEL_FILE} (trained on: {folder / META_FILE})")
    console.print(f"learning curve: {folder / CSV_FILE}, {folder / PNG_FILE}")
    if result.evaluations:
        console.print(f"final success rate: {result.evaluations[-1].success_rate:.0%}; replay it with "
                      f"`envfactory run {env_id} --policy {folder / MODEL_FILE}`")


@command()
def collect(
    env_id: str,
    episodes: int = typer.Option(100, "--episodes", "-n", min=1),
    dataset_id: Optional[str] = typer.Option(None, "--dataset-id", help="Minari dataset ID (default: "
                                                                        "envfactory/<id>/expert-v0)"),
    seed: int = typer.Option(0, help="Seed of the first episode; episode i uses seed + i"),
    data_path: Optional[Path] = typer.Option(None, "--data-path", help="Datasets folder (default: Minari's, "
                                                                       "MINARI_DATASETS_PATH or ~/.minari/datasets)"),
    overwrite: bool = typer.Option(False, "--overwrite", help="Replace a dataset of the same ID"),
    kwarg: List[str] = typer.Option(None, "--kwarg", "-k", help=KWARG_HELP),
):
    """Run the scripted expert and write its episodes as a Minari dataset (load with minari.load_dataset)."""

    _known(env_id)
    _require(extra.COLLECT_MODULES, "envfactory collect")


    kwargs = _parse_kwargs(kwarg)
    if registry.records()[env_id].backend != "pybullet":
        _fail(f"{env_id}: collect runs simulated IDs only (it would drive the real arm for every episode)")
    try:
        result = run_collection(env_id, episodes, dataset_id=dataset_id, seed=seed, env_kwargs=kwargs,
                                data_path=data_path, overwrite=overwrite)
    except FileExistsError as exc:
        _fail(str(exc))
    console.print(f"dataset {result.dataset_id}: {result.episodes} episodes, {result.steps} steps, "
                  f"{result.successes} reach the goal; written to {result.path}")
    console.print(f"load it with: import minari; minari.load_dataset({result.dataset_id!r})"
                  + (f" (with MINARI_DATASETS_PATH={data_path.resolve()})" if data_path else ""))
