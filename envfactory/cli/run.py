"""The main job and what it measures on a real path: run, sensing-spec."""

from __future__ import annotations

import json
from pathlib import Path
from typing import List, Optional

import typer
from rich.table import Table

from envfactory import factory
from envfactory.backends.base import BackendError
from envfactory.cli.common import (
    KWARG_HELP,
    allow_real_option,
    check_output,
    command,
    console,
    errors,
    fail,
    known_id,
    make_kwargs,
    model_file,
    override_option,
    real_arm_kwargs,
)
from envfactory.envs.episodes import iter_episodes, success_rate
from envfactory.experts import make_policy
from envfactory.learn.models import ModelMismatch
from envfactory.learn.runs import RunFolderError
from envfactory.learn.spec_folders import register_recorded
from envfactory.learn.trainer import load_policy, read_meta
from envfactory.schema.errors import SpecError
from envfactory.terms.sensing_from_log import read_log, sensing_terms, sensing_yaml

VIDEO_SUFFIXES = (".mp4", ".gif", ".webm", ".avi", ".mkv")


@command()
def run(
    env_id: str,
    episodes: int = typer.Option(5, "--episodes", "-n", min=1),
    policy: str = typer.Option(
        "scripted", help="'scripted' (the task's expert), 'random', or a model.zip saved by `envfactory train`"
    ),
    algo: Optional[str] = typer.Option(None, help="Algorithm of a --policy model with no model.json beside it"),
    seed: int = typer.Option(0, help="Seed of the first episode; episode i uses seed + i"),
    video: Optional[Path] = typer.Option(None, help="Record the episodes to this video file (e.g. out.mp4)"),
    override: List[str] = override_option(),
    kwarg: List[str] = typer.Option(None, "--kwarg", "-k", help=KWARG_HELP),
    allow_real_robot_motion: bool = allow_real_option(),
    stop_at_success: bool = typer.Option(
        False,
        "--stop-at-success",
        help="End each episode at its first success, even on Dense IDs (which go on to "
        "the time limit), so Length reads as time-to-success",
    ),
    timing_log: Optional[Path] = typer.Option(
        None,
        "--timing-log",
        help="Real IDs: write each step's info['timing'] (joint reading age, repeats, command "
        "latency) as JSON lines, for `envfactory sensing-spec`",
    ),
):
    """The main job: run episodes and print a per-episode table.

    Each episode ends where the env ends it (terminated or truncated), as a learner sees it: Return, Length
    and Success (is_success at the last step) are the learner's; "First success" is the step the goal was
    first reached. --stop-at-success ends episodes there instead."""
    import gymnasium as gym
    from rich.progress import Progress

    saved = None
    if policy not in ("scripted", "random"):
        saved, trained_kwargs = _saved_policy(policy)  # a user ID's spec folder, recorded with the model, joins
    known_id(env_id)
    # the env a model was trained on (a Real ID without what only a simulator has), unless -k or -o say otherwise
    kwargs = make_kwargs(kwarg, override, real_arm_kwargs(env_id, trained_kwargs) if saved is not None else None)
    if video is not None:
        check_output(video, VIDEO_SUFFIXES)
    if allow_real_robot_motion:
        kwargs["allow_real_robot_motion"] = True
    try:
        env = gym.make(env_id, render_mode="rgb_array" if video else None, **kwargs)
    except (SpecError, KeyError, gym.error.Error, BackendError) as exc:
        fail(str(exc).strip("'\""))
    frames, results, failure = [], [], ""
    if timing_log is not None and env.unwrapped.blueprint.backend != "rosbridge":
        env.close()
        fail(
            f"--timing-log records a real path's timing; {env_id} is simulated (its readings are never late): "
            f"use a Real ID"
        )
    try:
        timing = timing_log.open("w") if timing_log is not None else None
    except OSError as exc:
        env.close()
        fail(f"--timing-log {timing_log}: {exc.strerror}")

    def on_step(info: dict) -> None:
        progress.advance(task)
        if timing is not None and "timing" in info:
            timing.write(json.dumps(info["timing"]) + "\n")

    try:
        actor = _bind_model(saved, env, algo) if saved is not None else make_policy(policy, env, seed)
        limit = env.spec.max_episode_steps or 100
        with Progress(console=console, transient=True) as progress:
            task = progress.add_task(f"{env_id} ({policy})", total=episodes * limit)
            # the first reset is the first episode's: a real arm drives home once
            for result in iter_episodes(
                env,
                actor,
                episodes,
                seed,
                on_frame=frames.append if video else None,
                on_step=on_step,
                stop_on_success=stop_at_success,
            ):
                results.append(result)
    except KeyboardInterrupt:
        env.close()  # before the message: on a real robot this sends the stop
        _print_results(env_id, policy, results, stop_at_success)
        errors.print("interrupted: the env is closed and the arm stopped")
        raise typer.Exit(130)
    except (ValueError, BackendError) as exc:
        failure = str(exc)
    finally:
        env.close()
        if timing is not None:
            timing.close()
    _print_results(env_id, policy, results, stop_at_success)
    if timing_log is not None:
        console.print(f"timing log: {timing_log} (envfactory sensing-spec {timing_log} turns it into sensing terms)")
    if failure:
        fail(f"the run stopped after {len(results)} of {episodes} episodes: {failure}")
    if video:
        import imageio

        fps = env.unwrapped.metadata.get("render_fps", 2)
        imageio.mimsave(video, frames, fps=max(1, int(round(fps))) * 2, macro_block_size=8)
        console.print(f"video: {video} ({len(frames)} frames)")


@command("sensing-spec")
def sensing_spec(
    log_file: Path = typer.Argument(..., help="A timing log written by `envfactory run REAL_ID --timing-log`"),
    env_id: str = typer.Option(..., "--id", help="The ID the sensing terms are for: its action cycle sets the step"),
    cycle_time: Optional[float] = typer.Option(
        None,
        "--cycle-time",
        min=1e-3,
        help="Seconds a step, when the terms are for another action cycle than the ID's (its action_cycle_time kwarg)",
    ),
):
    """Sensing terms from what the real path measured: a timing log of joint reading ages, repeats and command
    latencies becomes observation_delay, action_delay and repeated_readings terms in whole steps, printed as a
    block to paste into the robot YAML (or under task.randomization)."""
    known_id(env_id)
    try:
        records = read_log(log_file)
        cycle = cycle_time or factory.blueprint(env_id).spec.env.timing.action_cycle_time
    except (OSError, ValueError) as exc:
        fail(str(exc))
    terms, facts = sensing_terms(records, cycle)
    console.print(sensing_yaml(terms, facts, str(log_file)), highlight=False, markup=False, end="")


def _saved_policy(path_text: str) -> tuple[Path, dict]:
    """A model file saved by `envfactory train` and the env kwargs it was trained with."""

    path = model_file(path_text, "'scripted', 'random'")
    meta = read_meta(path)
    if meta.get("env_id"):
        try:
            register_recorded(meta, path)
        except RunFolderError as exc:
            fail(str(exc))
    return path, dict(meta.get("env_kwargs", {}))


def _bind_model(path: Path, env, algo: str | None):
    """The saved model acting in `env`; a model trained on other spaces is refused before it acts."""

    try:
        return load_policy(path, env, algo)
    except ModelMismatch as exc:
        env.close()
        fail(f"--policy {exc}")


# What the table measures: (its title's tail, the footnote under it), by --stop-at-success.
EPISODE_END = {
    False: (
        "each episode until the env ends it",
        "Episodes end where the env ends them (terminated or truncated), as a learner sees them; Success is "
        "is_success at the last step.",
    ),
    True: (
        "each episode until its first success",
        "Episodes end at their first success (--stop-at-success), else where the env ends them: on IDs that go on "
        "after success (Dense) Length and Return stop short of what a learner sees.",
    ),
}


def _print_results(env_id: str, policy: str, results, stop_at_success: bool) -> None:
    aborted = any(r.abort_reason for r in results)
    columns = ["Episode", "Seed", "Return", "Length", "Success", "First success", "Rejected actions"]
    scope, footnote = EPISODE_END[stop_at_success]
    table = Table(*columns, *(["Aborted"] if aborted else []), title=f"{env_id} — {policy} — {scope}")
    for r in results:
        row = [
            str(r.index),
            str(r.seed),
            f"{r.episode_return:.2f}",
            str(r.length),
            "yes" if r.success else "no",
            "-" if r.first_success is None else f"step {r.first_success}",
            str(r.rejected),
        ]
        table.add_row(*row, *([r.abort_reason] if aborted else []))
    console.print(table)
    console.print(footnote, highlight=False)
    aborts = sum(bool(r.abort_reason) for r in results)
    console.print(
        f"success rate: {success_rate(results):.0%} over {len(results)} episodes"
        + (f"; {aborts} aborted by a fault" if aborts else "")
    )
