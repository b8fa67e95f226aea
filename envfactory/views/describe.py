"""Describe a blueprint the way the reference pages lay out an env, index tables first: printed by `envfactory
describe`, listed part by part for the docs site's env pages
(devkit/docs/generate.py renders the parts as Markdown)."""

from __future__ import annotations

from dataclasses import dataclass

from rich import box
from rich.console import Console
from rich.table import Table

from envfactory.compiler import Blueprint
from envfactory.compiler.scene_checks import height_summary
from envfactory.envs.managers import ObservationManager, RewardManager
from envfactory.geometry.frames import TaskFrame
from envfactory.geometry.object_press import ObjectPressGuard
from envfactory.geometry.robot_model import robot_geometry
from envfactory.geometry.safety import SafetyCheck
from envfactory.terms.goal_parts import GoalParts


def _table(title: str, *columns: str) -> Table:
    return Table(*columns, title=title, box=box.SIMPLE_HEAD, title_justify="left", show_edge=False)


def observation_table(compiled: Blueprint) -> Table:
    manager = ObservationManager(compiled.policy_observation)
    name = "observation (Box)" if compiled.goal_env else "Observation"
    scaled = (
        " normalised (normalize_observations): each column's declared bounds → [-1, 1]"
        + (", both goals by the goal box" if compiled.goal_env else "")
        if compiled.spec.env.observation.normalize
        else ""
    )
    table = _table(f"{name}: Box({manager.size},){scaled}", "Idx", "Dim", "Component", "Source", "Unit")
    for row in manager.table():
        table.add_row(*row)
    return table


def goal_size(compiled: Blueprint) -> int:
    """The desired (and achieved) goal's size: three coordinates for each point the goal places, four for each
    orientation."""
    return GoalParts.of(compiled.spec.task.goal).size


def goal_table(compiled: Blueprint) -> Table:
    goal = compiled.spec.task.goal
    table = _table(f"desired_goal: Box({goal_size(compiled)},)", "Idx", "Dim", "Component", "Min", "Max")
    low, high = GoalParts.of(goal).stacked_bounds(*goal.box)
    several = len(goal.parts) > 1
    names = [f"{name}'s goal {axis}" if several else f"goal {axis}" for name in goal.parts for axis in "xyz"]
    names += [f"{name}'s orientation q{axis}" for name in goal.orientation for axis in "xyzw"]
    for index, name in enumerate(names):
        table.add_row(str(index), "1", name, f"{low[index]:.3f}", f"{high[index]:.3f}")
    return table


def action_table(compiled: Blueprint) -> Table:
    layout = compiled.action
    mode = "EE" if layout.ee else "Joint"
    detail = f"delta × {layout.delta_coeff:g}" if layout.delta else "absolute"
    if layout.normalize:
        # the declared rows stay the Min/Max; the policy's [-1, 1] maps onto them row by row
        table = _table(
            f"Action: Box(-1, 1, ({layout.size},)) normalised (normalize_actions) — {mode} mode, {detail}",
            "Num",
            "Action",
            "Min",
            "Max",
            "Policy [-1, 1] →",
            "Joint",
            "Unit",
        )
        scale = layout.scale
        for index, row in enumerate(layout.rows):
            table.add_row(
                str(index), row.label, f"{row.low:+.2f}", f"{row.high:+.2f}", scale.mapping(index), row.joint, row.unit
            )
        return table
    table = _table(
        f"Action: Box({layout.size},) — {mode} mode, {detail}", "Num", "Action", "Min", "Max", "Joint", "Unit"
    )
    for index, row in enumerate(layout.rows):
        table.add_row(str(index), row.label, f"{row.low:+.2f}", f"{row.high:+.2f}", row.joint, row.unit)
    return table


def reward_table(compiled: Blueprint) -> Table:
    spec = compiled.spec
    table = _table(
        f"Reward ({spec.env.reward_type}), tolerance {spec.task.goal.tolerance:g} m",
        "Name",
        "Term",
        "Params",
        "Weight",
        "Meaning",
    )
    manager = RewardManager(compiled.rewards, spec.task.goal.tolerance, compiled.info_keys)
    for row in manager.table():
        table.add_row(*row)
    return table


def image_table(compiled: Blueprint) -> Table:
    camera = compiled.spec.scene.camera
    table = _table(
        f"Camera images (use_kinect): eye {list(camera.eye)} → target {list(camera.target)}, fov {camera.fov:g}°",
        "Key",
        "Shape",
        "Dtype",
        "Low",
        "High",
        "Meaning",
    )
    for image in compiled.images:
        table.add_row(
            image.name,
            str(image.shape),
            image.term.dtype.__name__,
            f"{image.low:g}",
            f"{image.high:g}",
            image.term.description,
        )
    return table


def ros_table(compiled: Blueprint) -> Table:
    """A Real ID's wiring: where it reads and what it publishes."""
    ros, real = compiled.spec.robot.ros, compiled.spec.env.real
    table = _table(
        f"rosbridge ws://{real.host}:{real.port}, task frame {ros.task_frame_id}", "Direction", "Topic", "Type"
    )
    table.add_row("in", ros.joint_states.topic, ros.joint_states.type)
    for name in compiled.spec.task.objects:
        table.add_row(f"in ({name})", ros.object_poses[name].topic, ros.object_poses[name].type)
    table.add_row("out (arm)", ros.arm_command.topic, ros.arm_command.type)
    uses_gripper = compiled.action.gripper_in_action or compiled.spec.gripper_at_reset is not None
    if ros.gripper_command is not None and uses_gripper:
        command, ends = ros.gripper_command, compiled.spec.robot.gripper
        direction = (
            "out (gripper)"
            if command.states is None
            else (
                f"out (gripper: open/close only; nearer {ends.closed:g} sends {command.states.closed!r}, "
                f"else {command.states.open!r})"
            )
        )
        table.add_row(direction, command.topic, command.type)
    return table


def _event_values(slot) -> str:
    bound, unit = slot.bound, slot.term.unit
    values = f"{bound.low:g} … {bound.high:g}{' ' + unit if unit else ''}, {bound.distribution.replace('_', '-')}"
    return values if bound.target == "" else f"{bound.target}: {values}"


def _when(slot) -> str:
    if slot.every is None:
        return "reset"
    every = slot.every
    return f"reset, every {every.steps} steps" if every.steps is not None else f"reset, every {every.seconds:g} s"


def randomization_table(compiled: Blueprint) -> Table:
    """The declared events (each with the absolute range it samples) and sensing terms."""
    state = "on" if compiled.randomized else "off; randomize=True turns it on"
    table = _table(f"Randomization ({state})", "Name", "Term", "Samples / does", "When")
    for slot in compiled.events:
        table.add_row(slot.name, slot.term.name, _event_values(slot), _when(slot))
    for slot in compiled.sensing:
        fields = type(slot.params).model_fields
        # a value left at its default (no bias, every observation) says nothing; a required one always shows
        params = ", ".join(
            f"{key}={value}"
            for key, value in slot.params.model_dump().items()
            if fields[key].is_required() or value not in ([], 0.0)
        )
        table.add_row(slot.name, slot.term.name, params, "every step")
    return table


def task_lines(compiled: Blueprint) -> list[str]:
    """Objects, gripper use and the lift stage: what the reset sets up."""
    task, spec = compiled.spec.task, compiled.spec
    lines = [height_summary(spec)]  # a goal or spawn height given in the wrong frame or unit shows here first
    for name, obj in task.objects.items():
        spawn = obj.spawn
        where = f"± {list(spawn.offset)} in x, y" if spawn.random else "fixed"
        lines.append(f"Object {name}: {_solid(obj)}, {obj.mass:g} kg, spawns at {list(spawn.position)} ({where})")
    for name, fixture in task.fixtures.items():
        touch = f", the fingers may touch {', '.join(fixture.touchable)}" if fixture.touchable else ""
        lines.append(
            f"Fixture {name}: {fixture.urdf} at {list(fixture.position)}, turned {fixture.yaw}°, joint "
            f"{fixture.joint!r} closed at reset ({fixture.friction:g} N friction, {fixture.damping:g} N s/m){touch}"
        )
    if spec.gripper_at_reset is not None or task.gripper.in_action:
        use = "action[-1], absolute" if task.gripper.in_action else "not in the action"
        lines.append(f"Gripper: {spec.gripper_at_reset} at reset, {use}")
    lift = task.goal.lift
    if lift is not None and lift.enabled:
        lines.append(
            f"Lift stage (multi_goal): current goal = spawn + [0, 0, {lift.height:g}] until reached "
            f"within tolerance, then the goal"
        )
    return lines


def value_at(spec, dotted: str):
    """The value at a dotted spec path, or None where the path does not exist (an optional block unset)."""
    node = spec
    for part in dotted.split("."):
        if node is None:
            return None
        node = node.get(part) if isinstance(node, dict) else getattr(node, part, None)
    return node


def kwarg_paths(spec) -> dict[str, str]:
    """Every gym.make kwarg a composed spec accepts, by name, with the spec path it sets (the family's
    aliases and its task's)."""
    return dict(sorted({**spec.kwargs, **spec.task.kwargs}.items()))


def kwarg_lines(compiled: Blueprint) -> list[str]:
    """Every gym.make kwarg of the ID with the value it has here: kwargs and overrides show."""
    spec = compiled.spec
    values = [f"{name}={value_at(spec, path)!r}" for name, path in kwarg_paths(spec).items()]
    return ["Kwargs: " + ", ".join(values)]


def id_summary(compiled: Blueprint) -> tuple[str, str, str, str, str]:
    """Robot, task, backend, observation size and action size: an ID's row in `envfactory list`."""
    size = goal_size(compiled)
    obs = str(compiled.observation_size) + (f" + goal {size}+{size}" if compiled.goal_env else "")
    return compiled.spec.robot.name, compiled.spec.task.name, compiled.backend, obs, str(compiled.action.size)


def safety_table(compiled: Blueprint) -> Table:
    """The geometry the safety check keeps clear: each link's collision shapes and what they are checked against."""
    collision = robot_geometry(compiled.spec, compiled.asset_root, compiled.fixture_folders).collision
    settings = compiled.spec.env.safety
    margin = settings.surface_margin
    table = _table(
        f"Safety: every shape ≥ {margin:g} m (+{SafetyCheck.SHAPE_TOLERANCE * 1000:g} mm per robot shape in a "
        f"pair, for engine differences) from {', '.join(o.name for o in collision.obstacles)} "
        f"(table footprint +{settings.table_footprint_margin:g} m) and from the arm's other links; "
        f"joint change ≤ {settings.max_joint_delta:g} rad",
        "Link",
        "Shape",
        "Size (m)",
        "Margin (m)",
        "Self pairs checked",
    )
    checked: dict[int, int] = {}
    for a, b in zip(collision.self_a, collision.self_b):
        checked[a] = checked.get(a, 0) + 1
        checked[b] = checked.get(b, 0) + 1
    for index, (shape, geometry_object) in enumerate(zip(collision.shapes, collision.geometry.geometryObjects)):
        moving = "" if shape.joint else " (fixed base)"
        table.add_row(
            shape.link + moving,
            _shape_kind(geometry_object.geometry),
            _shape_size(geometry_object.geometry),
            f"{margin + shape.padding:g}",
            str(checked.get(index, 0)),
        )
    skipped = len(collision.ignored)
    table.caption = (
        f"{collision.pair_count} pairs measured ({len(collision.scene_shape)} link–obstacle, "
        f"{len(collision.self_a)} link–link); {skipped} link pairs skipped as rigid, adjacent, "
        f"gripper mechanism or proven apart"
    )
    objects = compiled.spec.task.objects
    if objects:
        guard = ObjectPressGuard(collision, objects, TaskFrame.of(compiled.spec.robot))
        links = list(dict.fromkeys(collision.shapes[i].link for i in guard.guarded))
        table.caption += (
            f". No motion may end with {', '.join(links)} inside the {', '.join(objects)} while it rests "
            f"on the table (the fingers may touch it)"
        )
    return table


def _shape_kind(geometry) -> str:
    name = type(geometry).__name__
    return "mesh (convex hull)" if name in ("Convex", "ConvexBase") else name.lower()


def _shape_size(geometry) -> str:
    import numpy as np

    name = type(geometry).__name__
    if name == "Box":
        return "× ".join(f"{2 * v:.3f}" for v in geometry.halfSide).replace("× ", " × ")
    if name in ("Cylinder", "Capsule"):
        return f"r {geometry.radius:.3f}, l {2 * geometry.halfLength:.3f}"
    if name == "Sphere":
        return f"r {geometry.radius:.3f}"
    points = np.asarray(geometry.points())
    extent = points.max(axis=0) - points.min(axis=0)
    return f"{len(points)} points, {' × '.join(f'{v:.3f}' for v in extent)}"


def _turn(rpy) -> str:
    return f" turned rpy {list(rpy)}" if any(rpy) else ""


@dataclass(frozen=True)
class Part:
    """One piece of a description, a table or a line, in the order `envfactory describe` prints them. `kind`
    names what it shows, so two IDs' descriptions compare piece by piece (the docs' family pages do)."""

    kind: str
    body: Table | str
    plain: bool = False  # a long line of values: printed unhighlighted and soft-wrapped


def env_kind(compiled: Blueprint) -> str:
    return "goal-conditioned (Dict)" if compiled.goal_env else "standard (Box)"


def description_parts(compiled: Blueprint) -> list[Part]:
    """The description of a blueprint: what the console prints and what the docs' Markdown renders."""
    spec = compiled.spec
    parts = [
        Part(
            "summary",
            f"[bold]{compiled.env_id}[/] — {spec.robot.label}, {spec.task.label}, "
            f"{env_kind(compiled)}, backend {compiled.backend}, frame {spec.robot.task_frame}, "
            f"base at {list(spec.robot.mount)}{_turn(spec.robot.mount_rpy)}, "
            f"max_episode_steps {compiled.max_episode_steps}",
        ),
        Part("observation", observation_table(compiled)),
    ]
    if compiled.goal_env:
        parts.append(Part("goal", goal_table(compiled)))
        sources = (
            " then ".join([*("EE" if name == "ee" else name for name in spec.task.goal.parts)])
            + " XYZ"
            + "".join(f", then {name}'s orientation (x, y, z, w)" for name in spec.task.goal.orientation)
        )
        parts.append(
            Part(
                "achieved goal",
                f"achieved_goal: Box({goal_size(compiled)},) — current {sources}, same frame as desired_goal\n",
            )
        )
    else:
        goal = spec.task.goal
        parts.append(Part("goal", f"Goal box: min {list(goal.box[0])}, max {list(goal.box[1])}\n"))
    if compiled.images:
        parts.append(Part("images", image_table(compiled)))
    parts += [Part("task", line) for line in task_lines(compiled)]
    if compiled.backend == "rosbridge" and compiled.spec.robot.ros is not None:
        parts.append(Part("ros", ros_table(compiled)))
        real = compiled.spec.env.real
        parts.append(
            Part(
                "gates",
                f"Gates: motion {'allowed' if real.allow_motion else 'closed'} "
                f"(allow_real_robot_motion), joint states ≤ {real.joint_state_timeout_s:g} s old, "
                f"object poses ≤ {real.cube_pose_timeout_s:g} s old, "
                f"deadman {real.deadman_s:g} s\n",
            )
        )
    if compiled.events or compiled.sensing:
        parts.append(Part("randomization", randomization_table(compiled)))
    parts += [
        Part("action", action_table(compiled)),
        Part("safety", safety_table(compiled)),
        Part("reward", reward_table(compiled)),
    ]
    active = [f"{t.name} ({t.term.name})" for t in compiled.terminations if t.active]
    parts.append(
        Part(
            "termination",
            f"Termination: {', '.join(active) or 'none on this reward type'}; "
            f"truncation at {compiled.max_episode_steps} steps",
        )
    )
    parts += [Part("kwargs", line, plain=True) for line in kwarg_lines(compiled)]
    return parts


def render_description(compiled: Blueprint, console: Console) -> None:
    for part in description_parts(compiled):
        if part.plain:
            console.print(part.body, highlight=False, soft_wrap=True)
        else:
            console.print(part.body)


def _solid(obj) -> str:
    if obj.shape == "cylinder":
        return f"cylinder ⌀{obj.size:g} m × {2 * obj.half_extents[2]:g} m high"
    return f"box {obj.size:g} m"
