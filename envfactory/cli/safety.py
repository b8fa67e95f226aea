"""Commands that show and maintain the safety geometry: collision-pairs and safety-view."""

from __future__ import annotations

from pathlib import Path

import typer

from envfactory import factory
from envfactory.cli.common import KWARG_HELP, command, console, fail, known_id, make_kwargs, override_option
from envfactory.cli.lookup import robot_ids, unknown_robot
from envfactory.geometry.robot_model import regenerate_pairs
from envfactory.registration import registry
from envfactory.registration.registry import record
from envfactory.schema.compose import load_env_spec
from envfactory.schema.errors import SpecError
from envfactory.views.safety_picture import render_clearance


def _robot_blueprint(name: str):
    """The ID named, or the first simulated ID of the robot named."""

    records = registry.records()
    if name in records:
        try:
            return factory.blueprint(name)
        except SpecError as exc:
            return _only_pairs_stale(name, exc) or fail(str(exc))
    robots = robot_ids()
    if name not in robots:
        fail(unknown_robot(name, list(robots), ids=tuple(records)))
    first_error = None
    for env_id in robots[name]:
        if records[env_id].backend != "sim":
            continue
        try:
            return factory.blueprint(env_id)
        except SpecError as exc:
            compiled = _only_pairs_stale(env_id, exc)
            if compiled is not None:
                return compiled
            first_error = first_error or exc
    fail(str(first_error) if first_error else f"robot {name!r} has no simulated (pybullet) ID to build it from")


class _Unchecked:
    """What `collision-pairs` needs of an ID whose only fault is the pair list it is about to rewrite."""

    def __init__(self, spec, asset_root: Path):
        self.spec, self.asset_root = spec, asset_root


def _loaded(env_id: str):
    entry = record(env_id)
    try:
        loaded = load_env_spec(entry.family, (), dict(entry.kwargs), {}, env_id=env_id)
    except SpecError:
        return None
    return _Unchecked(loaded.spec, loaded.file_of("robot.model").parent)


def _only_pairs_stale(env_id: str, error):
    """A stale or missing pair list must not stop the command that writes it."""
    if not all(problem.path == "robot.safety.collision_pairs" for problem in error.problems):
        return None
    return _loaded(env_id)


@command("collision-pairs")
def collision_pairs(
    robot: str = typer.Argument(..., help="Robot name (e.g. ur5e) or an env ID of it"),
    samples: int = typer.Option(20000, min=100, help="Random configurations to sample"),
    seed: int = typer.Option(0),
):
    """Sample the robot's self-collision pairs and write the file its YAML names (safety.collision_pairs)."""
    import time

    compiled = _robot_blueprint(robot)
    start = time.perf_counter()
    try:
        path = regenerate_pairs(compiled.spec, compiled.asset_root, samples, seed)
    except ValueError as exc:
        fail(str(exc))
    console.print(f"{path}: {samples} samples in {time.perf_counter() - start:.1f} s")


@command("safety-view")
def safety_view(
    env_id: str,
    out: Path = typer.Option(Path("safety.png"), "--out", help="PNG to write"),
    joints: str = typer.Option("", help="Comma-separated arm joint values (default: home)"),
    kwarg: list[str] = typer.Option(None, "--kwarg", "-k", help=KWARG_HELP),
    override: list[str] = override_option(),
):
    """Render the arm with its checked collision shapes, coloured by clearance (red near, green clear)."""

    known_id(env_id)
    if not out.parent.exists():
        fail(f"--out {out}: the folder {out.parent} does not exist")
    compiled = factory.blueprint(env_id, **make_kwargs(kwarg, override))
    q_arm = None
    if joints:
        try:
            q_arm = [float(v) for v in joints.split(",")]
        except ValueError:
            fail(f"--joints {joints!r}: write comma-separated numbers")
    try:
        lowest = render_clearance(compiled, out, q_arm)
    except ValueError as exc:
        fail(str(exc))
    console.print(f"{out}: lowest clearance {lowest:.3f} m")
