"""The `envfactory` command: validate, list, describe, register, unregister, terms, run, twin.

Bad input never ends in a traceback: every command reports the error in one
message and exits 1 (`--debug` shows the traceback instead).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import List, Optional

import typer
from rich.table import Table
from typer.core import TyperCommand

# first of the package: importing cli.app drops PyBullet's load-time banner, before anything below loads PyBullet
from envfactory.cli.app import (KWARG_HELP, _check_output, _fail, _known, _parse_kwargs, app, command, console,
                                errors, model_file)
from envfactory import factory, registry, user_config
from envfactory.sensing_spec import read_log, sensing_terms, sensing_yaml
from envfactory.backends.base import BackendError
from envfactory.cli import learn as _learn_commands  # noqa: F401  (registers its commands)
from envfactory.cli import scale as _scale_commands  # noqa: F401  (registers its commands)
from envfactory.cli import safety as _safety_commands  # noqa: F401  (registers its commands)
from envfactory.cli.lookup import robots_with_backend, unknown_robot
from envfactory.compiler.scene_checks import height_summary
from envfactory.describe import render_description
from envfactory.episodes import iter_episodes, success_rate
from envfactory.experts import make_policy
from envfactory.learn.trainer import load_policy, read_meta
from envfactory.schema.compose import load_env_spec
from envfactory.schema.errors import SpecError
from envfactory.terms import catalog, plugins
from envfactory.twin import Twin
from envfactory.user_config import config_file


@command()
def validate(paths: List[Path] = typer.Argument(None, help="Spec folders or family files; default: every spec.")):
    """Compose and compile every ID of the given specs as make would; report errors with file:line."""

    missing = [path for path in paths or [] if not path.exists()]
    if missing:
        _fail("; ".join(f"{path}: no such file or folder{registry.nearest_entry(path)}" for path in missing))
    folders = paths or [registry.builtin_root(), *(folder for folder, _ in registry.user_folders())]
    targets, unread, notes = _validate_targets(folders, given=bool(paths))
    failures, checked = len(unread), 0
    for message in unread:
        errors.print(message, highlight=False, markup=False, soft_wrap=True)
    pending: dict = {}
    for path in targets:
        try:
            records = registry.scan_family(path, registry.search_roots(registry.folder_of(path)))
            clashes = [p for p in (registry.clash(r, pending) for r in records) if p is not None]
            if clashes:
                raise SpecError(clashes, path.stem)
            factory.check_family(records)
            pending.update({r.env_id: r for r in records})
            checked += len(records)
            if records:
                spec = load_env_spec(records[0].family, (), dict(records[0].kwargs), env_id=records[0].env_id).spec
                console.print(f"{path.stem}: {len(records)} ID(s) valid. {height_summary(spec)}", highlight=False,
                              soft_wrap=True)
        except SpecError as exc:
            failures += 1
            errors.print(str(exc), highlight=False, markup=False, soft_wrap=True)
    for note in notes:
        console.print(note, highlight=False, soft_wrap=True)
    if failures:
        _fail(f"{failures} spec file(s) invalid, {checked} ID(s) valid")
    console.print(f"{checked} ID(s) in {len(targets)} spec file(s): valid")


def _validate_targets(folders: list[Path], given: bool) -> tuple[list[Path], list[str], list[str]]:
    """The family files to validate; the messages of folders whose families are not read (refused: a family that
    is never registered must not pass unnoticed); notes on what `register` will make of a path."""
    targets, unread, notes = [], [], []
    for path in folders:
        if path.is_dir():
            listing = registry.list_folder(path)
            targets += listing.families
            unread += [f"{file}: {why}" for file, why in registry.unread_files(listing)]
        elif path.exists() or not given:
            targets.append(path)
            if given:
                notes.append(f"note: {path} is a family file; `envfactory register` and {registry.SPEC_PATH_VARIABLE} "
                             f"take its spec folder, {registry.folder_of(path)}")
    return targets, unread, notes


@command("list")
def list_ids(sources: bool = typer.Option(False, "--sources", help="Where the IDs come from: each spec folder")):
    """Every registered ID with its robot, task, backend and sizes."""

    if sources:
        _list_sources()
        return
    table = Table("ID", "Robot", "Task", "Backend", "Obs", "Action")
    for env_id, record in sorted(registry.records().items()):
        try:
            compiled = factory.blueprint(env_id)
        except SpecError as exc:
            table.add_row(env_id, "?", "?", record.backend, "invalid", str(exc.problems[0]) if exc.problems else "")
            continue
        obs = str(compiled.observation_size) + (" + goal 3+3" if compiled.goal_env else "")
        table.add_row(env_id, compiled.spec.robot.name, compiled.spec.task.name, compiled.backend, obs,
                      str(compiled.action.size))
    console.print(table)


def _list_sources() -> None:
    by_folder: dict[Path, list[str]] = {}
    for env_id, record in registry.records().items():
        by_folder.setdefault(registry.folder_of(record.family.path).resolve(), []).append(env_id)
    table = Table("Source", "Folder", "IDs", title=f"spec folders (config file: {config_file()})")
    folders = [(registry.builtin_root(), registry.BUILTIN_SOURCE), *registry.user_folders()]
    for folder, source in folders:
        ids = sorted(by_folder.get(folder.expanduser().resolve(), []))
        state = f"{len(ids)}" if folder.is_dir() else "0 (missing folder)"
        table.add_row(source, str(folder), state + (f": {', '.join(ids[:4])}{', …' if len(ids) > 4 else ''}"
                                                    if ids else ""))
    console.print(table)


@command()
def describe(
    env_id: str,
    overrides: List[str] = typer.Argument(None, help="Hydra overrides, e.g. env.action.ee=true"),
    kwarg: List[str] = typer.Option(None, "--kwarg", "-k", help=KWARG_HELP),
):
    """The observation index table, action table, reward terms and goal box of an ID."""

    _known(env_id)
    kwargs = _parse_kwargs(kwarg)
    render_description(factory.blueprint(env_id, overrides or (), **kwargs), console)


@command()
def register(
    paths: List[Path] = typer.Argument(..., help="Folders of user specs"),
    save: bool = typer.Option(True, "--save/--no-save", help="Record the folders in the user config file, so "
                                                             "later processes register them too"),
):
    """Validate user spec folders, smoke-build each simulated ID (reset plus one step), and record them."""

    failed = False
    for path in paths:
        if not path.is_dir():
            errors.print(f"{path}: {registry.not_a_folder(path)}", highlight=False, markup=False)
            failed = True
            continue
        factory.unregister_folder(path)  # registered lazily at import: validate it in full now
        added, problems = factory.register_specs(path)
        for problem in problems:
            failed = True
            errors.print(str(problem), highlight=False, markup=False, soft_wrap=True)
        failed |= not _smoke_build(added)
        if not added and not problems:
            errors.print(f"{path}: no family files (*.yaml) with IDs", highlight=False, markup=False)
            failed = True
        if save and added and not problems:
            new = user_config.add_folder(path)
            console.print(f"{'recorded' if new else 'already recorded'} {path.resolve()} in {user_config.config_file()}")
        elif save and problems:
            errors.print(f"{path}: not recorded in {user_config.config_file()}: fix the errors above and register "
                         f"again", highlight=False, markup=False)
    if failed:
        raise typer.Exit(1)


def _smoke_build(env_ids: list[str]) -> bool:
    import gymnasium as gym


    ok = True
    for env_id in env_ids:
        backend = registry.records()[env_id].backend
        if backend != "pybullet":
            console.print(f"registered {env_id} (backend {backend}: not smoke-built, it would need the robot)")
            continue
        try:
            env = gym.make(env_id)
            try:
                env.reset(seed=0)
                env.step(env.action_space.sample())
            finally:
                env.close()
            console.print(f"registered {env_id}: reset and step ok")
        except Exception as exc:  # report, keep going with the other IDs
            ok = False
            errors.print(f"{env_id}: smoke build failed: {exc}", highlight=False, markup=False)
    return ok


@command()
def unregister(paths: List[Path] = typer.Argument(..., help="Folders recorded by `envfactory register`")):
    """Forget recorded spec folders: later processes no longer register their IDs."""

    recorded = user_config.registered_folders()
    for path in paths:
        if user_config.remove_folder(path):
            console.print(f"removed {path.resolve()} from {user_config.config_file()}")
        else:
            known = ", ".join(map(str, recorded)) or "none"
            _fail(f"{path.resolve()} is not recorded in {user_config.config_file()} (recorded: {known})")


@command()
def terms(modules: List[str] = typer.Argument(None, help="Term modules to import first (as a spec's `terms:` "
                                                         "list names them, relative to the current folder)")):
    """Every observation, reward, termination, image, event and sensing term and every expert, with params, size
    and unit."""

    plugins.load_entry_points()
    for name in modules or []:
        try:
            plugins.import_module(name, Path.cwd())
        except Exception as exc:
            _fail(f"cannot import term module {name!r}: {type(exc).__name__}: {exc}")
    for title, columns, rows in catalog.TABLES:
        table = Table(title=title, title_justify="left")
        for index, column in enumerate(columns):
            table.add_column(column, no_wrap=index == 0)  # a term's name is what a spec types: never cut
        for row in rows():
            table.add_row(*row)
        console.print(table)


VIDEO_SUFFIXES = (".mp4", ".gif", ".webm", ".avi", ".mkv")


@command()
def run(
    env_id: str,
    episodes: int = typer.Option(5, "--episodes", "-n", min=1),
    policy: str = typer.Option("scripted", help="'scripted' (the task's expert), 'random', or a model.zip "
                                                 "saved by `envfactory train`"),
    algo: Optional[str] = typer.Option(None, help="Algorithm of a --policy model with no model.json beside it"),
    seed: int = typer.Option(0, help="Seed of the first episode; episode i uses seed + i"),
    video: Optional[Path] = typer.Option(None, help="Record the episodes to this video file (e.g. out.mp4)"),
    override: List[str] = typer.Option(None, "--override", "-o", help="Hydra override, repeatable"),
    kwarg: List[str] = typer.Option(None, "--kwarg", "-k", help=KWARG_HELP),
    allow_real_robot_motion: bool = typer.Option(
        False, "--allow-real-robot-motion", help="Let a Real ID move the arm (the motion gate); clear the workspace first"),
    stop_at_success: bool = typer.Option(
        False, "--stop-at-success", help="End each episode at its first success, even on Dense IDs (which go on to "
                                         "the time limit), so Length reads as time-to-success"),
    timing_log: Optional[Path] = typer.Option(
        None, "--timing-log", help="Real IDs: write each step's info['timing'] (joint reading age, repeats, command "
                                   "latency) as JSON lines, for `envfactory sensing-spec`"),
):
    """The main job: run episodes and print a per-episode table.

    Each episode ends where the env ends it (terminated or truncated), as a learner sees it: Return, Length
    and Success (is_success at the last step) are the learner's; "First success" is the step the goal was
    first reached. --stop-at-success ends episodes there instead."""
    import gymnasium as gym
    from rich.progress import Progress


    _known(env_id)
    kwargs = _parse_kwargs(kwarg)
    saved = None
    if policy not in ("scripted", "random"):
        saved, trained_kwargs = _saved_policy(policy)
        if registry.records()[env_id].backend == "rosbridge":
            # a model trained in simulation runs on the real arm as it is: what only a simulator has goes
            dropped = factory.simulation_only_kwargs(env_id, trained_kwargs)
            if dropped:
                console.print(f"{env_id} is a real arm: the model's simulation-only kwargs are left out: "
                              f"{', '.join(f'{name}={trained_kwargs[name]!r}' for name in dropped)}", highlight=False)
            trained_kwargs = {name: value for name, value in trained_kwargs.items() if name not in dropped}
        kwargs = {**trained_kwargs, **kwargs}  # the env it was trained on, unless -k says otherwise
    if video is not None:
        _check_output(video, VIDEO_SUFFIXES)
    if allow_real_robot_motion:
        kwargs["allow_real_robot_motion"] = True
    try:
        env = gym.make(env_id, overrides=override or [], render_mode="rgb_array" if video else None, **kwargs)
    except (SpecError, KeyError, gym.error.Error, BackendError) as exc:
        _fail(str(exc).strip("'\""))
    frames, results, failure = [], [], ""
    if timing_log is not None and env.unwrapped.blueprint.backend != "rosbridge":
        env.close()
        _fail(f"--timing-log records a real path's timing; {env_id} is simulated (its readings are never late): "
              f"use a Real ID")
    try:
        timing = timing_log.open("w") if timing_log is not None else None
    except OSError as exc:
        env.close()
        _fail(f"--timing-log {timing_log}: {exc.strerror}")

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
            for result in iter_episodes(env, actor, episodes, seed, on_frame=frames.append if video else None,
                                        on_step=on_step, stop_on_success=stop_at_success):
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
        _fail(f"the run stopped after {len(results)} of {episodes} episodes: {failure}")
    if video:
        import imageio

        fps = env.unwrapped.metadata.get("render_fps", 2)
        imageio.mimsave(video, frames, fps=max(1, int(round(fps))) * 2, macro_block_size=8)
        console.print(f"video: {video} ({len(frames)} frames)")


@command("sensing-spec")
def sensing_spec(
    log_file: Path = typer.Argument(..., help="A timing log written by `envfactory run REAL_ID --timing-log`"),
    env_id: str = typer.Option(..., "--id", help="The ID the sensing terms are for: its action cycle sets the step"),
    cycle_time: Optional[float] = typer.Option(None, "--cycle-time", min=1e-3,
                                               help="Seconds a step, when the terms are for another action cycle "
                                                    "than the ID's (its action_cycle_time kwarg)"),
):
    """Sensing terms from what the real path measured: a timing log of joint reading ages, repeats and command
    latencies becomes observation_delay, action_delay and repeated_readings terms in whole steps, printed as a
    block to paste into the robot YAML (or under task.randomization)."""
    _known(env_id)
    try:
        records = read_log(log_file)
        cycle = cycle_time or factory.blueprint(env_id).spec.env.timing.action_cycle_time
    except (OSError, ValueError) as exc:
        _fail(str(exc))
    terms, facts = sensing_terms(records, cycle)
    console.print(sensing_yaml(terms, facts, str(log_file)), highlight=False, markup=False, end="")


def _saved_policy(path_text: str) -> tuple[Path, dict]:
    """A model file saved by `envfactory train` and the env kwargs it was trained with."""

    path = model_file(path_text, "'scripted', 'random'")
    return path, dict(read_meta(path).get("env_kwargs", {}))


def _bind_model(path: Path, env, algo: str | None):
    """The saved model acting in `env`; a model trained on other spaces is refused before it acts."""

    try:
        return load_policy(path, env, algo)
    except Exception as exc:  # SB3 names the mismatching spaces; a zip that is no model lands here too
        env.close()
        space = env.observation_space
        shapes = {k: v.shape for k, v in space.spaces.items()} if hasattr(space, "spaces") else space.shape
        reason = str(exc).splitlines()[0][:160]
        _fail(f"--policy {path}: cannot act in {env.spec.id} (action shape {env.action_space.shape}, observation "
              f"shapes {shapes}): {type(exc).__name__}: {reason}; a model runs on the ID and kwargs it was "
              f"trained with (model.json beside it, or -k)")


# What the table measures: (its title's tail, the footnote under it), by --stop-at-success.
EPISODE_END = {
    False: ("each episode until the env ends it",
            "Episodes end where the env ends them (terminated or truncated), as a learner sees them; Success is "
            "is_success at the last step."),
    True: ("each episode until its first success",
           "Episodes end at their first success (--stop-at-success), else where the env ends them: on IDs that go on "
           "after success (Dense) Length and Return stop short of what a learner sees."),
}


def _print_results(env_id: str, policy: str, results, stop_at_success: bool) -> None:
    aborted = any(r.abort_reason for r in results)
    columns = ["Episode", "Seed", "Return", "Length", "Success", "First success", "Rejected actions"]
    scope, footnote = EPISODE_END[stop_at_success]
    table = Table(*columns, *(["Aborted"] if aborted else []), title=f"{env_id} — {policy} — {scope}")
    for r in results:
        row = [str(r.index), str(r.seed), f"{r.episode_return:.2f}", str(r.length), "yes" if r.success else "no",
               "-" if r.first_success is None else f"step {r.first_success}", str(r.rejected)]
        table.add_row(*row, *([r.abort_reason] if aborted else []))
    console.print(table)
    console.print(footnote, highlight=False)
    aborts = sum(bool(r.abort_reason) for r in results)
    console.print(f"success rate: {success_rate(results):.0%} over {len(results)} episodes"
                  + (f"; {aborts} aborted by a fault" if aborts else ""))


TWIN_ROBOT_HELP = "Robot name (the Robot column of `envfactory list`)"


class _TwinHelp(TyperCommand):
    """`twin --help` names the robots with a real path (a rosbridge ID), read from the registered specs when
    the help is shown: a robot YAML added later is listed without touching this file, and no other command
    pays for composing the families."""

    def format_help(self, ctx, formatter) -> None:
        robots = robots_with_backend("rosbridge")
        for param in self.params:
            if param.name == "robot":
                param.help = f"{TWIN_ROBOT_HELP}; robots with a real path: {', '.join(robots) or 'none'}"
        super().format_help(ctx, formatter)


@command(cls=_TwinHelp)
def twin(
    robot: str = typer.Argument(..., help=TWIN_ROBOT_HELP),
    task: str = typer.Option("push", help="The task whose objects it simulates (push has the cube)"),
    port: int = typer.Option(9090, help="Port of the rosbridge websocket; 0 picks a free one"),
    host: str = typer.Option("127.0.0.1", help="Interface to listen on (loopback by default)"),
    group_move: Optional[float] = typer.Option(None, help="Seconds every command without a duration takes (the "
                                                          "driver's stock time profile, until the env sets its "
                                                          "own); default: the driver's (xs_sdk: 2.0), else the "
                                                          "robot YAML's ros.arm_command.profile_time_s"),
    speed_scaling: float = typer.Option(1.0, min=0.0, max=1.0, help="The UR trajectory controller's speed scaling "
                                                                     "(the pendant's slider: 1.0 is 100%)"),
    delay: float = typer.Option(0.0, help="Fault: latency added to every published message, s"),
    stop_joint_states_after: Optional[float] = typer.Option(None, help="Fault: stop publishing joint states after S s"),
    stop_object_poses_after: Optional[float] = typer.Option(None, help="Fault: stop publishing the cube pose after S s"),
    freeze_after: Optional[float] = typer.Option(None, help="Fault: the driver freezes after S s (no joint states)"),
    freeze_for: float = typer.Option(2.0, help="... for this many seconds"),
    malformed_after: Optional[float] = typer.Option(None, help="Fault: publish malformed joint states after S s"),
    malformed_count: int = typer.Option(1, help="... this many (a NaN position, sent as null)"),
    kill_after: Optional[float] = typer.Option(None, help="Fault: the rosbridge server dies after S s"),
    down_for: float = typer.Option(4.0, help="... and comes back after this many seconds"),
    drop_after: Optional[float] = typer.Option(None, help="Fault: drop every connection after S s"),
    ignore_commands_after: Optional[float] = typer.Option(
        None, help="Fault: after S s the driver takes commands but executes none (a stopped controller)"),
    topic_type: List[str] = typer.Option(
        None, help="Fault: the driver registers TOPIC with another TYPE (TOPIC=TYPE), repeatable"),
    no_rosapi: bool = typer.Option(False, help="Fault: serve without rosapi (its services do not exist)"),
):
    """A rosbridge stand-in serving a PyBullet robot and cube on the real topics: rehearse Real IDs on it."""
    import time


    real_robots = robots_with_backend("rosbridge")
    if robot not in real_robots:
        _fail(unknown_robot(robot, real_robots, "robots with a real path"))
    types = {}
    for item in topic_type or []:
        topic, sep, type_name = item.partition("=")
        if not sep:
            _fail(f"--topic-type {item!r}: write TOPIC=TYPE")
        types[topic] = type_name
    try:
        stand_in = Twin(robot, task, host=host, port=port, topic_types=types, group_move_s=group_move,
                        speed_scaling=speed_scaling).start()
    except (ValueError, OSError) as exc:
        _fail(str(exc))
    ros, faults = stand_in.ros, stand_in.faults
    faults.delay_s, faults.no_rosapi = delay, no_rosapi
    console.print(f"twin of {robot} ({task}) at ws://{host}:{stand_in.port}, playing "
                  f"{ros.driver or 'the topic map as declared'}; "
                  f"publishing {ros.joint_states.topic} and {[t.topic for t in ros.object_poses.values()]}, "
                  f"executing {ros.arm_command.topic}"
                  f"{' and ' + ros.gripper_command.topic if ros.gripper_command else ''}. Ctrl-C stops it.")
    poses = [t.topic for t in ros.object_poses.values()]
    schedule = [(stop_joint_states_after, lambda: faults.silence(ros.joint_states.topic)),
                (stop_object_poses_after, lambda: [faults.silence(topic) for topic in poses]),
                (freeze_after, lambda: faults.silence(ros.joint_states.topic, freeze_for)),
                (malformed_after, lambda: faults.corrupt(ros.joint_states.topic, malformed_count)),
                (kill_after, lambda: stand_in.kill(down_for)),
                (drop_after, stand_in.drop_connections),
                (ignore_commands_after, lambda: setattr(faults, "ignore_commands", True))]
    start = time.monotonic()
    pending = sorted(((after, act) for after, act in schedule if after is not None), key=lambda item: item[0])
    try:
        while True:
            while pending and time.monotonic() - start >= pending[0][0]:
                pending.pop(0)[1]()
            time.sleep(0.05)
    except KeyboardInterrupt:
        console.print(f"twin stopped; its driver received {len(stand_in.received)} commands; "
                      f"the server refused {len(stand_in.server.errors)} messages")
    finally:
        stand_in.stop()


def main() -> None:  # pragma: no cover
    sys.exit(app())


if __name__ == "__main__":  # pragma: no cover
    main()
