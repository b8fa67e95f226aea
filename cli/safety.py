"""Commands that show and maintain the safety geometry: collision-pairs and safety-view."""

from __future__ import annotations

from pathlib import Path

import typer

from envfactory.cli.main import KWARG_HELP, _fail, _parse_kwargs, command, console


def _robot_blueprint(name: str):
    """The first ID of a robot (by robot name or by ID)."""
    import envfactory
    from envfactory.spec.errors import SpecError

    ids = sorted(envfactory.records())
    if name in ids:
        return envfactory.blueprint(name)
    for env_id in ids:
        try:
            compiled = envfactory.blueprint(env_id)
        except SpecError:
            continue
        if compiled.spec.robot.name == name and compiled.backend == "pybullet":
            return compiled
    robots = sorted({envfactory.blueprint(i).spec.robot.name for i in ids})
    _fail(f"no robot or ID named {name!r} (robots: {', '.join(robots)})")


@command("collision-pairs")
def collision_pairs(
    robot: str = typer.Argument(..., help="Robot name (e.g. ur5e) or an env ID of it"),
    samples: int = typer.Option(20000, min=100, help="Random configurations to sample"),
    seed: int = typer.Option(0),
):
    """Sample the robot's self-collision pairs and write the file its YAML names (safety.collision_pairs)."""
    import time

    from envfactory.collision_pairs import regenerate

    compiled = _robot_blueprint(robot)
    start = time.perf_counter()
    try:
        path = regenerate(compiled, samples, seed)
    except ValueError as exc:
        _fail(str(exc))
    console.print(f"{path}: {samples} samples in {time.perf_counter() - start:.1f} s")


@command("safety-view")
def safety_view(
    env_id: str,
    out: Path = typer.Option(Path("safety.png"), "--out", "-o", help="PNG to write"),
    joints: str = typer.Option("", help="Comma-separated arm joint values (default: home)"),
    kwarg: list[str] = typer.Option(None, "--kwarg", "-k", help=KWARG_HELP),
):
    """Render the arm with its checked collision shapes, coloured by clearance (red near, green clear)."""
    import envfactory
    from envfactory.safety_view import render_clearance

    if not out.parent.exists():
        _fail(f"--out {out}: the folder {out.parent} does not exist")
    compiled = envfactory.blueprint(env_id, **_parse_kwargs(kwarg))
    q_arm = None
    if joints:
        try:
            q_arm = [float(v) for v in joints.split(",")]
        except ValueError:
            _fail(f"--joints {joints!r}: write comma-separated numbers")
    try:
        lowest = render_clearance(compiled, out, q_arm)
    except ValueError as exc:
        _fail(str(exc))
    console.print(f"{out}: lowest clearance {lowest:.3f} m")
