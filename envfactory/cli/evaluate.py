"""`envfactory evaluate` (a policy over IDs and seeds, as a success table) and what every command that can run
on a Ray cluster shares: the --workers and --address options and the lazy import of the cluster wing.

Without --workers or --address everything runs in this process and Ray is never imported; with them the
episodes run as Ray tasks (trials as Ray Tune trials), and the results are the same, episode by episode."""

from __future__ import annotations

import csv
import statistics
from pathlib import Path
from types import ModuleType
from typing import List, Optional

import typer
from rich.table import Table
from tqdm import tqdm

from envfactory import cluster
from envfactory.cli.common import (
    KWARG_HELP,
    allow_real_option,
    check_output,
    command,
    console,
    fail,
    is_real,
    known_id,
    make_kwargs,
    model_file,
    override_option,
    real_arm_kwargs,
)
from envfactory.cluster import trials as trial_runs
from envfactory.cluster.bundles import FolderCopyError
from envfactory.cluster.work import PolicySource, SeedEvaluation, ShippedFolders, run_here
from envfactory.envs.episodes import EpisodeResult, success_rate
from envfactory.learn.extra import MissingExtra
from envfactory.learn.hyperparams import HyperparameterError
from envfactory.learn.runs import fresh_folder

WORKERS_HELP = (
    "Run as Ray tasks on this many workers (a local Ray instance of that many CPUs, or at most that "
    "many tasks at once on --address); the results equal a run in one process. Needs the \\[ray] extra"
)  # the backslash keeps Rich, which prints the help, from reading [ray] as a markup tag and dropping it
ADDRESS_HELP = "Run on the Ray cluster already running at this address (e.g. ray://head:10001, or auto)"


def workers_option():
    return typer.Option(None, "--workers", "-w", min=1, help=WORKERS_HELP)


def address_option():
    return typer.Option(None, "--address", help=ADDRESS_HELP)


def cluster_module(name: str, what: str) -> ModuleType:
    """envfactory.cluster.NAME, imported only now: it imports Ray, which a command run in one process never
    needs (nor pays for); without Ray installed, the command fails saying how to install it."""
    try:
        return cluster.load(name, what)
    except MissingExtra as exc:
        fail(str(exc))


def cluster_size(workers: int | None, address: str | None) -> int | None:
    """How many workers a command spreads over: None to run in this process; with only --address, the CPUs of
    that cluster."""
    if workers is None and address is None:
        return None
    return workers or 0  # 0: as many as the cluster has, read once connected (pool.cluster_cpus)


def simulated_only(env_id: str, command_name: str) -> None:
    if is_real(env_id):
        fail(
            f"{env_id}: {command_name} runs simulated IDs only (it would drive the real arm for every episode); "
            f"`envfactory run` or `evaluate {env_id} --allow-real-robot-motion` runs a real arm, one episode "
            "after another"
        )


def _real_arm_allowed(env_id: str, allowed: bool, size: int | None) -> None:
    if size is not None:
        fail(f"{env_id} drives a real arm: it runs here, one episode after another (drop --workers/--address)")
    if not allowed:
        fail(f"{env_id} drives a real arm for every episode: clear the workspace and pass --allow-real-robot-motion")


def _policy_source(policy: str, algo: str | None) -> PolicySource:
    if policy == "scripted":
        return PolicySource()
    path = model_file(policy, "'scripted'")
    return PolicySource.saved_model(path, algo)


@command()
def evaluate(
    env_id: List[str] = typer.Argument(..., metavar="ID...", help="The IDs to evaluate on"),
    policy: str = typer.Option(
        "scripted",
        help="'scripted' (each task's expert) or a model.zip saved by "
        "`envfactory train` (made with the kwargs in its model.json)",
    ),
    algo: Optional[str] = typer.Option(None, help="Algorithm of a --policy model with no model.json beside it"),
    episodes: int = typer.Option(20, "--episodes", "-n", min=1, help="Episodes per ID"),
    seed: int = typer.Option(0, help="Seed of the first episode; episode i uses seed + i, on every ID"),
    kwarg: List[str] = typer.Option(None, "--kwarg", "-k", help=KWARG_HELP),
    override: List[str] = override_option(),
    out_csv: Optional[Path] = typer.Option(
        None,
        "--csv",
        help="Also write every episode (ID, seed, return, length, success, first success) to this CSV file",
    ),
    workers: Optional[int] = workers_option(),
    address: Optional[str] = address_option(),
    allow_real_robot_motion: bool = allow_real_option(),
    progress: bool = typer.Option(True, "--progress/--no-progress", help="Show a progress bar"),
):
    """Run a policy over IDs and seeds and print its success table: each episode until the env ends it, as a
    learner sees it (Success: is_success at the last step). With --workers the episodes run as Ray tasks. A Real
    ID runs with --allow-real-robot-motion, in this process, one episode after another."""

    size = cluster_size(workers, address)
    for name in env_id:
        known_id(name)
        if is_real(name):
            _real_arm_allowed(name, allow_real_robot_motion, size)
    if out_csv is not None:
        check_output(out_csv, (".csv",))
    source = _policy_source(policy, algo)
    gate = {"allow_real_robot_motion": True} if allow_real_robot_motion else {}
    # -k and -o over the kwargs a model was trained with, which a Real ID takes without the simulation-only ones
    per_id = {
        name: {**make_kwargs(kwarg, override, real_arm_kwargs(name, source.trained_kwargs())), **gate}
        for name in env_id
    }
    try:  # the spec folders travel only to other processes: here the IDs are known already
        workspace = ShippedFolders() if size is None else ShippedFolders.for_ids(list(env_id))
    except FolderCopyError as exc:
        fail(str(exc))
    works = [SeedEvaluation(name, per_id[name], workspace, source) for name in env_id]
    seeds = range(seed, seed + episodes)
    if size is None:
        with tqdm(total=len(works) * episodes, unit="episode", disable=not progress, desc="episodes") as bar:
            results = [run_here(work, seeds, lambda _: bar.update()) for work in works]
    else:
        pool = cluster_module("pool", "evaluate --workers/--address")
        with pool.connected(size, address):
            results = pool.run_episodes_on_ray(works, seeds, pool.cluster_cpus(size), progress)
    _print_table(source.label, env_id, results, seeds)
    if out_csv is not None:
        _write_csv(out_csv, env_id, results)
        console.print(f"episodes: {out_csv}")


def _print_table(policy: str, env_ids: list[str], results: list[list[EpisodeResult]], seeds: range) -> None:
    table = Table(
        "ID",
        "Episodes",
        "Success",
        "Mean return",
        "Mean length",
        "Median first success",
        title=f"{policy} — seeds {seeds.start}..{seeds.stop - 1} — each episode until the env ends it",
    )
    for env_id, rows in zip(env_ids, results):
        firsts = [r.first_success for r in rows if r.first_success is not None]
        table.add_row(
            env_id,
            str(len(rows)),
            f"{success_rate(rows):.0%}",
            f"{statistics.fmean(r.episode_return for r in rows):.2f}",
            f"{statistics.fmean(r.length for r in rows):.1f}",
            f"step {statistics.median(firsts):g}" if firsts else "-",
        )
    console.print(table)
    pooled = [r for rows in results for r in rows]
    console.print(f"success rate: {success_rate(pooled):.0%} over {len(pooled)} episodes", highlight=False)


CSV_COLUMNS = ("env_id", "seed", "episode_return", "length", "success", "first_success", "rejected", "abort_reason")


def _write_csv(path: Path, env_ids: list[str], results: list[list[EpisodeResult]]) -> None:
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(CSV_COLUMNS)
        for env_id, rows in zip(env_ids, results):
            for r in rows:
                writer.writerow(
                    [
                        env_id,
                        r.seed,
                        repr(r.episode_return),
                        r.length,
                        int(r.success),
                        "" if r.first_success is None else r.first_success,
                        r.rejected,
                        r.abort_reason,
                    ]
                )


SEEDS_HELP = (
    "Train one run per seed (comma-separated: 0,1,2), each in its own folder inside the group folder "
    "(--out, default runs/ID-ALGO-seeds0-1-2); then a summary table and the curves of all of them"
)
SWEEP_HELP = "Train every seed once per value: name=value1,value2 (values as -p takes them), repeatable for a grid"


def parse_seeds(text: str) -> list[int]:
    try:
        seeds = [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        fail(f"--seeds {text!r}: write whole numbers separated by commas, e.g. 0,1,2")
    if not seeds or len(set(seeds)) != len(seeds):
        fail(f"--seeds {text!r}: give one or more different seeds, e.g. 0,1,2")
    return seeds


def train_trials(
    env_id: str,
    algo: str,
    seeds: list[int],
    sweep_items: list[str],
    out: Path | None,
    overrides: tuple[str, ...],
    steps: int | None,
    env_kwargs: dict,
    eval_every: int | None,
    eval_episodes: int | None,
    demos: str | None,
    workers: int | None,
    address: str | None,
    progress: bool,
) -> None:
    """`envfactory train ID --seeds ... [--sweep ...]`: every trial, here or as Ray Tune trials, then the summary."""
    try:
        sweep = trial_runs.parse_sweep(sweep_items)
        asked = out or Path("runs") / f"{env_id}-{algo.lower()}-seeds{'-'.join(map(str, seeds))}"
        group = fresh_folder(asked)
        planned = trial_runs.plan(
            env_id, group, seeds, sweep, algo, overrides, steps, env_kwargs, eval_every, eval_episodes, demos
        )
    except (HyperparameterError, FolderCopyError) as exc:
        fail(str(exc))
    if group != asked:
        console.print(f"{asked} holds earlier runs, which are never overwritten: these go to {group}")
    trial_runs.open_group(group, planned)
    console.print(f"{len(planned)} trials of {env_id} ({algo}) in {group}")
    size = cluster_size(workers, address)
    if size is None:
        with tqdm(total=len(planned), unit="trial", disable=not progress, desc="trials") as bar:
            outcomes = trial_runs.run_here(planned, lambda _: bar.update())
    else:
        pool = cluster_module("pool", "train --seeds with --workers/--address")
        tuning = cluster_module("tuning", "train --seeds with --workers/--address")
        with pool.connected(size, address):
            outcomes = tuning.run_trials(planned, pool.cluster_cpus(size), progress)
    rows = trial_runs.write_summary(group, outcomes, f"{env_id} ({algo.upper()}), {len(planned)} trials")
    _print_trials(rows, group)


def _percent(value) -> str:
    return "-" if value is None else f"{value:.0%}"


def _print_trials(rows: list[dict], group: Path) -> None:
    table = Table("Trial", "Final success", "Best success", "Steps", "Wall s", "Error", title=f"trials in {group}")
    for row in rows:
        table.add_row(
            row["trial"],
            _percent(row["final_success"]),
            _percent(row["best_success"]),
            str(row["timesteps"]),
            f"{row['wall_s']:.0f}",
            row["error"] or "",
        )
    console.print(table)
    for setting, finished, mean, spread in trial_runs.by_setting(rows):
        outcome = (
            f"final success {mean:.0%} ± {spread:.0%} over {finished} finished trial(s)"
            if finished
            else "no trial finished"
        )
        console.print(f"{setting or 'all seeds'}: {outcome}", highlight=False)
    curves = [
        group / name for name in (trial_runs.CURVES_FILE, trial_runs.WALL_CURVES_FILE) if (group / name).is_file()
    ]
    console.print(
        f"summary: {group / trial_runs.SUMMARY_FILE}" + (f"; curves: {', '.join(map(str, curves))}" if curves else "")
    )
    failed = sum(bool(row["error"]) for row in rows)
    if failed:
        fail(f"{failed} of {len(rows)} trials failed (their errors are in the table and in the summary)")
