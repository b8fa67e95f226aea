"""The `envfactory` command: validate, list, describe, register, run."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import List, Optional

import typer
from rich.console import Console
from rich.table import Table

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="A config-driven factory of Gymnasium environments for robot arms.")
# Tables stay whole when the output is piped or captured.
_WIDTH = None if sys.stdout.isatty() else 140
console = Console(width=_WIDTH)
errors = Console(stderr=True, width=_WIDTH)


def _fail(message: str, code: int = 1) -> None:
    errors.print(f"[bold red]error:[/] {message}", highlight=False, markup=True)
    raise typer.Exit(code)


@app.command()
def validate(paths: List[Path] = typer.Argument(None, help="Spec folders or family files; default: every spec.")):
    """Compose and compile every ID of the given specs; report errors with file:line."""
    import envfactory.registry as registry
    from envfactory.compiler import compile_blueprint
    from envfactory.spec.compose import load_env_spec
    from envfactory.spec.errors import SpecError

    targets: list[Path] = []
    for path in paths or [registry.builtin_root(), *registry.environment_folders()]:
        targets.extend(registry.family_files(path) if path.is_dir() else [path])
    failures, checked = 0, 0
    for path in targets:
        try:
            for record in registry.scan_family(path, registry.search_roots(registry.folder_of(path))):
                loaded = load_env_spec(record.family, (), dict(record.kwargs))
                compile_blueprint(loaded, record.env_id, record.backend, record.goal_env)
                checked += 1
        except SpecError as exc:
            failures += 1
            errors.print(str(exc), highlight=False, markup=False)
    if failures:
        _fail(f"{failures} spec file(s) invalid, {checked} ID(s) valid")
    console.print(f"{checked} ID(s) in {len(targets)} spec file(s): valid")


@app.command("list")
def list_ids():
    """Every registered ID with its robot, task, backend and sizes."""
    import envfactory
    from envfactory.spec.errors import SpecError

    table = Table("ID", "Robot", "Task", "Backend", "Obs", "Action")
    for env_id, record in sorted(envfactory.records().items()):
        try:
            compiled = envfactory.blueprint(env_id)
        except SpecError as exc:
            table.add_row(env_id, "?", "?", record.backend, "invalid", str(exc).splitlines()[1].strip())
            continue
        obs = str(compiled.observation_size) + (" + goal 3+3" if compiled.goal_env else "")
        table.add_row(env_id, compiled.spec.robot.name, compiled.spec.task.name, compiled.backend, obs,
                      str(compiled.action.size))
    console.print(table)


def _parse_kwargs(items: List[str] | None) -> dict:
    import yaml

    kwargs = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep:
            _fail(f"--kwarg {item!r}: write name=value")
        kwargs[name] = yaml.safe_load(value)
    return kwargs


KWARG_HELP = "gym.make kwarg as name=value, repeatable"


@app.command()
def describe(
    env_id: str,
    overrides: List[str] = typer.Argument(None, help="Hydra overrides, e.g. env.action.ee=true"),
    kwarg: List[str] = typer.Option(None, "--kwarg", "-k", help=KWARG_HELP),
):
    """The observation index table, action table, reward terms and goal box of an ID."""
    import envfactory
    from envfactory.describe import render_description
    from envfactory.spec.errors import SpecError

    kwargs = _parse_kwargs(kwarg)
    try:
        compiled = envfactory.blueprint(env_id, overrides or (), **kwargs)
    except (SpecError, KeyError) as exc:
        _fail(str(exc).strip("'\""))
    render_description(compiled, console)


@app.command()
def register(paths: List[Path] = typer.Argument(..., help="Folders of user specs")):
    """Register user spec folders and smoke-build each new simulated ID (reset plus one step)."""
    import gymnasium as gym

    import envfactory

    failed = False
    for path in paths:
        added, problems = envfactory.register_specs(path)
        for problem in problems:
            failed = True
            errors.print(str(problem), highlight=False, markup=False)
        for env_id in added:
            if envfactory.records()[env_id].backend != "pybullet":
                console.print(f"registered {env_id} (backend {envfactory.records()[env_id].backend}: not smoke-built, "
                              f"it would need the robot)")
                continue
            try:
                env = gym.make(env_id)
                env.reset(seed=0)
                env.step(env.action_space.sample())
                env.close()
                console.print(f"registered {env_id}: reset and step ok")
            except Exception as exc:  # report, keep going with the other IDs
                failed = True
                errors.print(f"{env_id}: smoke build failed: {exc}", highlight=False, markup=False)
    if failed:
        raise typer.Exit(1)


@app.command()
def run(
    env_id: str,
    episodes: int = typer.Option(5, "--episodes", "-n", min=1),
    policy: str = typer.Option("scripted", help="'scripted' (the task's expert) or 'random'"),
    seed: int = typer.Option(0, help="Seed of the first episode; episode i uses seed + i"),
    video: Optional[Path] = typer.Option(None, help="Record the episodes to this video file (e.g. out.mp4)"),
    override: List[str] = typer.Option(None, "--override", "-o", help="Hydra override, repeatable"),
    kwarg: List[str] = typer.Option(None, "--kwarg", "-k", help=KWARG_HELP),
    allow_real_robot_motion: bool = typer.Option(
        False, "--allow-real-robot-motion", help="Let a Real ID move the arm (the motion gate); clear the workspace first"),
):
    """The main job: run episodes and print a per-episode table."""
    import gymnasium as gym
    from rich.progress import Progress

    import envfactory  # noqa: F401  (registers the IDs)
    from envfactory.backends.base import BackendError
    from envfactory.episodes import iter_episodes
    from envfactory.experts import make_policy
    from envfactory.spec.errors import SpecError

    kwargs = _parse_kwargs(kwarg)
    if allow_real_robot_motion:
        kwargs["allow_real_robot_motion"] = True
    try:
        env = gym.make(env_id, overrides=override or [], render_mode="rgb_array" if video else None, **kwargs)
    except (SpecError, KeyError, gym.error.Error, BackendError) as exc:
        _fail(str(exc).strip("'\""))
    frames, results, failure = [], [], ""
    try:
        actor = make_policy(policy, env, seed)
        limit = env.spec.max_episode_steps or 100
        with Progress(console=console, transient=True) as progress:
            task = progress.add_task(f"{env_id} ({policy})", total=episodes * limit)
            # the first reset is the first episode's: a real arm drives home once
            for result in iter_episodes(env, actor, episodes, seed, on_frame=frames.append if video else None,
                                        on_step=lambda: progress.advance(task)):
                results.append(result)
    except KeyboardInterrupt:
        env.close()  # before the message: on a real robot this sends the stop
        _print_results(env_id, policy, results)
        errors.print("interrupted: the env is closed and the arm stopped")
        raise typer.Exit(130)
    except (ValueError, BackendError) as exc:
        failure = str(exc)
    finally:
        env.close()
    _print_results(env_id, policy, results)
    if failure:
        _fail(f"the run stopped after {len(results)} of {episodes} episodes: {failure}")
    if video:
        import imageio

        fps = env.unwrapped.metadata.get("render_fps", 2)
        imageio.mimsave(video, frames, fps=max(1, int(round(fps))) * 2, macro_block_size=8)
        console.print(f"video: {video} ({len(frames)} frames)")


def _print_results(env_id: str, policy: str, results) -> None:
    from envfactory.episodes import success_rate

    aborted = any(r.abort_reason for r in results)
    columns = ["Episode", "Seed", "Return", "Length", "Success", "Rejected actions"] + (["Aborted"] if aborted else [])
    table = Table(*columns, title=f"{env_id} — {policy}")
    for r in results:
        row = [str(r.index), str(r.seed), f"{r.episode_return:.2f}", str(r.length), "yes" if r.success else "no",
               str(r.rejected)]
        table.add_row(*row, *([r.abort_reason] if aborted else []))
    console.print(table)
    aborts = sum(bool(r.abort_reason) for r in results)
    console.print(f"success rate: {success_rate(results):.0%} over {len(results)} episodes"
                  + (f"; {aborts} aborted by a fault" if aborts else ""))


@app.command()
def twin(
    robot: str = typer.Argument(..., help="Robot name: ur5e or vx300s"),
    task: str = typer.Option("push", help="The task whose objects it simulates (push has the cube)"),
    port: int = typer.Option(9090, help="Port of the rosbridge websocket; 0 picks a free one"),
    host: str = typer.Option("127.0.0.1", help="Interface to listen on (loopback by default)"),
    group_move: float = typer.Option(2.0, help="VX300S: seconds every group command takes (xs_sdk time profile)"),
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

    from envfactory.twin import Twin

    types = {}
    for item in topic_type or []:
        topic, sep, type_name = item.partition("=")
        if not sep:
            _fail(f"--topic-type {item!r}: write TOPIC=TYPE")
        types[topic] = type_name
    try:
        stand_in = Twin(robot, task, host=host, port=port, topic_types=types, group_move_s=group_move).start()
    except (ValueError, OSError) as exc:
        _fail(str(exc))
    ros, faults = stand_in.ros, stand_in.faults
    faults.delay_s, faults.no_rosapi = delay, no_rosapi
    console.print(f"twin of {robot} ({task}) at ws://{host}:{stand_in.port}; "
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


from envfactory.cli import safety as _safety_commands  # noqa: E402,F401  (registers its commands)


def main() -> None:  # pragma: no cover
    sys.exit(app())


if __name__ == "__main__":  # pragma: no cover
    main()
