"""Several training runs of one ID: one per seed, times each setting of a sweep, run one after another in this process
or one per Ray Tune trial (tuning.py). Each trial is an ordinary `envfactory train` run with its own run folder (model,
record, curve) inside the group folder; the group gets a summary table and the curves of all of them.

A trial writes its folder where it runs. On one machine that is the group folder itself; on a cluster of
several machines the group folder must be on a filesystem every node mounts: the head leaves a marker with
a fresh token in it, and a trial that cannot read the token refuses to start, naming the folder and the node,
rather than write a run no one will find.
"""

from __future__ import annotations

import csv
import itertools
import re
import socket
import statistics
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from envfactory.cluster.work import ShippedFolders
from envfactory.learn.curve import Evaluation, plot
from envfactory.learn.hyperparams import HyperparameterError
from envfactory.learn.models import checked_hyperparameters
from envfactory.learn.trainer import train

MARKER_FILE = ".trials"  # in the group folder: the token that proves a worker sees the same folder
SUMMARY_FILE, CURVES_FILE, WALL_CURVES_FILE = "summary.csv", "curves.png", "curves_wall.png"


class TrialError(RuntimeError):
    """A trial that cannot run where it landed."""


@dataclass(frozen=True)
class Trial:
    env_id: str
    folder: str  # absolute: the worker's working folder is not the head's
    algo: str
    seed: int
    setting: tuple[str, ...]  # this trial's sweep overrides (name=value), after the command's own
    overrides: tuple[str, ...]
    steps: int | None
    env_kwargs: dict
    eval_every: int | None
    eval_episodes: int | None
    demos: str | None
    workspace: ShippedFolders
    token: str  # the group marker's content

    @property
    def label(self) -> str:
        return " ".join([f"seed {self.seed}", *self.setting])


@dataclass
class TrialOutcome:
    trial: Trial
    evaluations: list[Evaluation] = field(default_factory=list)
    error: str = ""


def parse_sweep(items: list[str]) -> dict[str, list[str]]:
    """`name=v1,v2` items as {name: [v1, v2]}; commas inside brackets stay in their value ([64,64])."""
    sweep: dict[str, list[str]] = {}
    for item in items:
        name, sep, values = item.partition("=")
        parts = _top_level_split(values)
        if not sep or not name or not all(parts):
            raise HyperparameterError(f"--sweep {item!r}: write name=value1,value2 (values as -p takes them)")
        if name in sweep:
            raise HyperparameterError(f"--sweep {name}: given twice; list every value in one --sweep")
        sweep[name] = parts
    return sweep


def _top_level_split(text: str) -> list[str]:
    parts, depth, current = [], 0, ""
    for char in text:
        if char in "[{(":
            depth += 1
        elif char in "]})":
            depth -= 1
        if char == "," and depth == 0:
            parts.append(current.strip())
            current = ""
        else:
            current += char
    return parts + [current.strip()]


def plan(
    env_id: str,
    group: Path,
    seeds: list[int],
    sweep: dict[str, list[str]],
    algo: str,
    overrides: tuple[str, ...],
    steps: int | None,
    env_kwargs: dict,
    eval_every: int | None,
    eval_episodes: int | None,
    demos: str | None,
) -> list[Trial]:
    """Every trial (seeds × sweep settings), each setting's hyperparameters checked before anything runs."""
    settings = [
        tuple(f"{name}={value}" for name, value in zip(sweep, values)) for values in itertools.product(*sweep.values())
    ] or [()]
    for setting in settings:
        checked_hyperparameters(algo, env_id, (*overrides, *setting))  # a bad name or value fails here, named
    group = group.expanduser().resolve()
    workspace = ShippedFolders.for_ids([env_id])
    token = uuid.uuid4().hex
    return [
        Trial(
            env_id,
            str(group / _folder_name(seed, setting)),
            algo,
            seed,
            setting,
            overrides,
            steps,
            env_kwargs,
            eval_every,
            eval_episodes,
            demos,
            workspace,
            token,
        )
        for setting in settings
        for seed in seeds
    ]


def _folder_name(seed: int, setting: tuple[str, ...]) -> str:
    return re.sub(r"[^A-Za-z0-9_.=+-]", "_", "-".join([f"seed{seed}", *setting]))


def open_group(group: Path, trials: list[Trial]) -> None:
    """Make the group folder and leave the marker the trials look for."""
    group.mkdir(parents=True, exist_ok=True)
    (group / MARKER_FILE).write_text(trials[0].token)


def run_trial(trial: Trial, on_evaluation: Callable[[Evaluation], None] | None = None) -> TrialOutcome:
    """One trial, in this process: a train run in its folder."""
    folder = Path(trial.folder)
    marker = folder.parent / MARKER_FILE
    try:
        seen = marker.read_text()
    except OSError:
        seen = ""
    if seen != trial.token:
        raise TrialError(
            f"{trial.label}: this worker ({socket.gethostname()}) does not see the group folder "
            f"{folder.parent}; on a cluster of several machines give --out a folder on a filesystem "
            f"every node mounts"
        )
    trial.workspace.enter([trial.env_id])
    result = train(
        trial.env_id,
        folder,
        algo=trial.algo,
        seed=trial.seed,
        steps=trial.steps,
        overrides=(*trial.overrides, *trial.setting),
        env_kwargs=trial.env_kwargs,
        eval_every=trial.eval_every,
        eval_episodes=trial.eval_episodes,
        demos=trial.demos,
        progress_bar=False,
        on_evaluation=on_evaluation,
    )
    return TrialOutcome(trial, result.evaluations)


ANSI_CODES = re.compile(r"\x1b\[[0-9;]*m")


def failure_text(error: BaseException) -> str:
    """What a failed trial's summary row says: the error at the bottom of the wrappers a cluster adds (a Ray
    task error names the task and its process on its first line, in terminal colours; its `cause` is what
    the trial raised), its type and first line, without colour codes."""
    for _ in range(8):  # a wrapper may wrap a wrapper
        cause = getattr(error, "cause", None)
        if not isinstance(cause, BaseException):
            break
        error = cause
    lines = [line.strip() for line in ANSI_CODES.sub("", str(error)).splitlines() if line.strip()]
    return f"{type(error).__name__}: {lines[0] if lines else 'no message'}"


def run_here(trials: list[Trial], on_done: Callable[[TrialOutcome], None] | None = None) -> list[TrialOutcome]:
    """The trials one after another in this process; a failed one is recorded and the others go on, as on a
    cluster."""
    outcomes = []
    for trial in trials:
        try:
            outcome = run_trial(trial)
        except Exception as exc:  # reported in the summary, as a failed task is
            outcome = TrialOutcome(trial, error=failure_text(exc))
        outcomes.append(outcome)
        if on_done is not None:
            on_done(outcome)
    return outcomes


SUMMARY_COLUMNS = (
    "trial",
    "seed",
    "setting",
    "final_success",
    "best_success",
    "timesteps",
    "wall_s",
    "folder",
    "error",
)


def summary_rows(outcomes: list[TrialOutcome]) -> list[dict]:
    rows = []
    for outcome in outcomes:
        curve, trial = outcome.evaluations, outcome.trial
        rows.append(
            {
                "trial": Path(trial.folder).name,
                "seed": trial.seed,
                "setting": " ".join(trial.setting),
                "final_success": curve[-1].success_rate if curve else None,
                "best_success": max(e.success_rate for e in curve) if curve else None,
                "timesteps": curve[-1].timesteps if curve else 0,
                "wall_s": curve[-1].wall_s if curve else 0.0,
                "folder": trial.folder,
                "error": outcome.error,
            }
        )
    return rows


def by_setting(rows: list[dict]) -> list[tuple[str, int, float, float]]:
    """(setting, finished trials, mean and standard deviation of their final success) per sweep setting."""
    grouped: dict[str, list[float]] = {}
    for row in rows:
        grouped.setdefault(row["setting"], [])
        if row["final_success"] is not None:
            grouped[row["setting"]].append(row["final_success"])
    return [
        (
            setting,
            len(values),
            statistics.fmean(values) if values else float("nan"),
            statistics.pstdev(values) if values else float("nan"),
        )
        for setting, values in grouped.items()
    ]


def write_summary(group: Path, outcomes: list[TrialOutcome], title: str) -> list[dict]:
    """summary.csv and the curves of every finished trial (against steps, and against wall-clock time)."""
    rows = summary_rows(outcomes)
    with open(group / SUMMARY_FILE, "w", newline="") as handle:
        writer = csv.DictWriter(handle, SUMMARY_COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    curves = {outcome.trial.label: outcome.evaluations for outcome in outcomes if outcome.evaluations}
    if curves:
        plot(curves, group / CURVES_FILE, title)
        plot(curves, group / WALL_CURVES_FILE, title, x="wall_s")
    return rows
