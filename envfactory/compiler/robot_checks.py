"""What `make` would find out, found without physics: the URDF assembles and loads,
every joint, frame and link the spec names exists, the home pose clears the table,
and the goal and spawn points are within the arm's reach.

The checks run on the shared geometry the env will use (`geometry.robot_model`),
so what is checked here is what runs there.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pinocchio as pin

from envfactory.compiler.expert_points import expert_points
from envfactory.compiler.inertia_checks import inertia_problems
from envfactory.geometry.collision_pairs import INPUTS, PADDING, WHAT_CHANGED, StalePairs, pairs_file
from envfactory.geometry.frames import nearest_top_down
from envfactory.geometry.robot_model import RobotGeometry, robot_geometry
from envfactory.geometry.urdf_assembly import AssemblyError, assemble, resolve_part_path
from envfactory.schema.errors import suggest
from envfactory.schema.folders import builtin_root, folder_of
from envfactory.schema.models import ComposedSpec
from envfactory.schema.sources import Findings
from envfactory.schema.units import out_of_range_hint

# Slack on the URDF's joint limits: YAML limits rounded to two decimals (1.26 for 1.2566).
LIMIT_SLACK = 0.005
# The goal box is probed at its centre and its 8 corners, and every probe must be reachable:
# goals are drawn uniformly from the whole box, so an unreachable corner is a share of
# episodes whose goal the arm cannot reach (the design's "goal and spawn boxes reachable").

PAIRS_PATH = "robot.safety.collision_pairs"

_found: dict[str, tuple[tuple[str, str], ...]] = {}  # what the checks found, per robot, task, scene and settings


def check(
    spec: ComposedSpec,
    asset_root: Path,
    found: Findings,
    family: Path | None = None,
    env_id: str = "",
    fixture_folders=(),
) -> None:
    """Every problem `make` or `reset` would hit in the robot model and the reach of the task. The checks
    run once per robot, task, scene and settings: what they find is kept as (dotted path, message). `family`
    and `env_id` say whose pair list it is, for the advice on writing it."""
    key = "\0".join(
        (
            spec.robot.model_dump_json(),
            spec.task.model_dump_json(),
            spec.scene.model_dump_json(),
            spec.env.safety.model_dump_json(),
            spec.workspace.model_dump_json(),
            str(asset_root),
            _pairs_text(spec, asset_root),
            str(tuple(fixture_folders)),
        )
    )
    if key not in _found:
        _found[key] = tuple(_problems(spec, asset_root, fixture_folders))
    for path, message in _found[key]:
        if path == PAIRS_PATH:
            written = found.sources.locate("robot.safety.padding")
            # the padding found to have changed (not just listed among the inputs): say where the user wrote it
            if INPUTS[PADDING] in message.partition(WHAT_CHANGED)[2] and written.file:
                message += f" (written at {written.file}:{written.line})"
            message += f"; {_pairs_advice(spec, asset_root, family, env_id)}"
        found.add(path, message)


def _pairs_advice(spec: ComposedSpec, asset_root: Path, family: Path | None, env_id: str) -> str:
    """How to write the pair list, never into the installed package for a user's family: a list there serves
    the robot as shipped, and a user's padding or edits need a list of their own."""
    robot = spec.robot.name
    builtin = builtin_root().resolve()
    folder = folder_of(family).resolve() if family is not None else builtin
    if folder == builtin:
        return f"run `envfactory collision-pairs {robot}` to write it"
    command = f"`envfactory collision-pairs {env_id or robot} --specs {folder}`"
    pairs = pairs_file(spec, asset_root)
    if pairs is not None and pairs.resolve().is_relative_to(builtin):
        own = folder / "robots" / f"{robot}.collision.yaml"
        return (
            f"that list belongs to the installed envfactory package and serves robot {robot!r} as shipped: do not "
            f"rewrite it. Write a list of your own into your folder: point the robot at it in {family} with "
            f"`robot: {{safety: {{collision_pairs: {own}}}}}` (a relative path is read from the robot YAML's "
            f"folder, {asset_root}), then run {command}"
        )
    return f"run {command} to write it (into {pairs}, the file robot.safety.collision_pairs names)"


def _pairs_text(spec: ComposedSpec, asset_root: Path) -> str:
    pairs = pairs_file(spec, asset_root)
    return pairs.read_text() if pairs is not None and pairs.is_file() else ""


def _problems(spec: ComposedSpec, asset_root: Path, fixture_folders=()) -> list[tuple[str, str]]:
    try:
        urdf = assemble(spec.robot.model, asset_root, spec.robot.name)
    except AssemblyError as exc:
        return [(exc.path, str(exc))]
    try:
        # the bare model, not the shared chain: the chain needs the names checked here to exist
        model = pin.buildModelFromUrdf(str(urdf))
    except Exception as exc:  # Pinocchio raises plain RuntimeError/ValueError with its own text
        return [("robot.model", f"Pinocchio cannot load the assembled URDF: {exc}")]
    problems = _name_problems(spec, model) + [
        (f"robot.model.parts.{index}.urdf", problem)
        for index, part in enumerate(spec.robot.model.parts)
        for problem in inertia_problems(resolve_part_path(part, asset_root, f"robot.model.parts.{index}"))
    ]
    if problems:
        return problems
    problems = _padding_problems(spec, model) + _gripper_direction_problems(spec, model)
    pairs = pairs_file(spec, asset_root)
    if pairs is not None and not pairs.is_file():
        problems.append((PAIRS_PATH, f"no file {pairs}: the robot's collision pair list is not written yet"))
    if problems:
        return problems
    try:
        geometry = robot_geometry(spec, asset_root, fixture_folders)
    except StalePairs as exc:
        return [(PAIRS_PATH, str(exc))]
    except (ValueError, ArithmeticError, np.linalg.LinAlgError, RuntimeError) as exc:
        # a model whose numbers break the kinematics or the collision geometry
        return [("robot.model", f"the kinematics or collision geometry fail on this robot model: {exc}")]
    links = geometry.collision.links
    bare = [
        (
            f"robot.safety.padding.{name}",
            f"link {name!r} has no collision geometry: its padding would change "
            f"nothing (links with geometry: {', '.join(links)})",
        )
        for name in spec.robot.safety.padding
        if name not in links
    ]
    if bare:
        return bare
    try:
        problems = _pose_problems(spec, geometry) + _reach_problems(spec, geometry)
        return problems or _expert_problems(spec, geometry)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        return [("robot.model", f"the kinematics fail on this robot model: {exc}")]


def _name_problems(spec: ComposedSpec, model) -> list[tuple[str, str]]:
    robot = spec.robot
    joints = {model.names[i]: i for i in range(1, model.njoints)}
    frames = {frame.name for frame in model.frames}
    problems = []

    def joint(path: str, name: str, need_limits: tuple[float, float] | None = None) -> None:
        if name not in joints:
            problems.append((path, f"the URDF has no joint {name!r}{suggest(name, joints)}"))
            return
        j = model.joints[joints[name]]
        if j.nq != 1:
            problems.append(
                (
                    path,
                    f"joint {name!r} must have one degree of freedom (a revolute or prismatic "
                    f"joint; continuous joints are not supported)",
                )
            )
            return
        if need_limits is not None:
            low, high = model.lowerPositionLimit[j.idx_q], model.upperPositionLimit[j.idx_q]
            if need_limits[0] < low - LIMIT_SLACK or need_limits[1] > high + LIMIT_SLACK:
                hint = (
                    next(
                        filter(
                            None,
                            (
                                out_of_range_hint(key, value, low, high)
                                for key, value in (("lower", need_limits[0]), ("upper", need_limits[1]))
                            ),
                        ),
                        "",
                    )
                    if model.joints[joints[name]].shortname().startswith("JointModelR")
                    else ""
                )  # revolute: radians
                problems.append(
                    (
                        path.rsplit(".", 1)[0],
                        f"limits [{need_limits[0]:g}, {need_limits[1]:g}] of "
                        f"{name!r} exceed the URDF's [{low:.4g}, {high:.4g}]{hint}",
                    )
                )

    for index, arm_joint in enumerate(robot.arm_joints):
        joint(f"robot.arm_joints.{index}.name", arm_joint.name, (arm_joint.lower, arm_joint.upper))
    for index, entry in enumerate(robot.joint_states):
        joint(f"robot.joint_states.{index}.{'urdf' if entry.urdf else 'name'}", entry.urdf_joint)
    if robot.gripper is not None:
        gripper = robot.gripper
        joint("robot.gripper.joint", gripper.joint, (gripper.low, gripper.high))
        for name, gain in gripper.mimic.items():
            follows = sorted((gain * gripper.low, gain * gripper.high))
            joint(f"robot.gripper.mimic.{name}.gain", name, (follows[0], follows[1]))
        for index, link in enumerate(robot.gripper.pads.links):
            if link not in frames:
                problems.append(
                    (f"robot.gripper.pads.links.{index}", f"the URDF has no link {link!r}{suggest(link, frames)}")
                )
    if robot.ee_frame not in frames:
        problems.append(
            ("robot.ee_frame", f"the URDF has no frame {robot.ee_frame!r}{suggest(robot.ee_frame, frames)}")
        )
    return problems


def _gripper_direction_problems(spec: ComposedSpec, model) -> list[tuple[str, str]]:
    """`closed` must be the way the fingers close in the URDF: swapped, the expert's grasp opens the fingers,
    and every grasp test reads an open gripper as a closed one. Judged on the pads' distance (or, without pads,
    the gripper links'): it must shrink from open to closed."""
    gripper = spec.robot.gripper
    if gripper is None:
        return []
    links = list(gripper.pads.links) or _gripper_links(model, gripper)
    frames = [model.getFrameId(link) for link in links if model.existFrame(link)]
    if len(frames) < 2:
        return []
    data = model.createData()

    def spans(value: float) -> np.ndarray:
        q = pin.neutral(model)
        for name, gain in [(gripper.joint, 1.0), *gripper.mimic.items()]:
            q[model.joints[model.getJointId(name)].idx_q] = gain * value
        pin.framesForwardKinematics(model, data, q)
        points = [data.oMf[frame].translation.copy() for frame in frames]
        return np.array([np.linalg.norm(a - b) for a, b in itertools.combinations(points, 2)])

    at_open, at_closed = spans(gripper.open), spans(gripper.closed)
    pair = int(np.argmax(np.abs(at_closed - at_open)))  # the pair the gripper moves the most
    if at_closed[pair] <= at_open[pair] + 1e-4:
        return []
    a, b = list(itertools.combinations([link for link in links if model.existFrame(link)], 2))[pair]
    closing = "smaller" if gripper.open < gripper.closed else "larger"  # toward `open`, the nearer the pads
    return [
        (
            "robot.gripper.closed",
            f"open ({gripper.open:g}) and closed ({gripper.closed:g}) look swapped: in the "
            f"URDF {a} and {b} are {at_open[pair] * 1000:.1f} mm apart at open and "
            f"{at_closed[pair] * 1000:.1f} mm at closed, so 'closed' opens the fingers (they "
            f"close toward {closing} values of {gripper.joint}); swap the two values",
        )
    ]


def _gripper_links(model, gripper) -> list[str]:
    """The links the gripper's joints move, for a gripper that names no pads."""
    joints = {model.getJointId(name) for name in (gripper.joint, *gripper.mimic) if model.existJointName(name)}
    return [frame.name for frame in model.frames if frame.type == pin.FrameType.BODY and frame.parentJoint in joints]


def _padding_problems(spec: ComposedSpec, model) -> list[tuple[str, str]]:
    """A padded link the URDF lacks would silently keep no extra clearance."""
    links = {frame.name for frame in model.frames}
    return [
        (f"robot.safety.padding.{name}", f"the URDF has no link {name!r}{suggest(name, links)}")
        for name in spec.robot.safety.padding
        if name not in links
    ]


def _pose_problems(spec: ComposedSpec, geometry: RobotGeometry) -> list[tuple[str, str]]:
    home = np.asarray(spec.robot.home, float)
    gripper = spec.gripper_assumed_at_reset
    verdict = geometry.safety_check(spec.env.safety).check(
        home, home, gripper
    )  # a motion of length zero: the home pose itself
    if not verdict.accepted:
        return [
            (
                "robot.home",
                f"the home pose is unsafe ({verdict.reason}; the margin is "
                f"{spec.env.safety.surface_margin:g} m): every reset would start there",
            )
        ]
    return []


def _probes(low: np.ndarray, high: np.ndarray) -> list[np.ndarray]:
    corners = [np.array(c) for c in itertools.product(*zip(low, high))]
    return [(low + high) / 2, *corners]


def _point(point) -> str:
    return "[" + ", ".join(f"{float(v):g}" for v in np.round(point, 3)) + "]"


def _reach_problems(spec: ComposedSpec, geometry: RobotGeometry) -> list[tuple[str, str]]:
    safety = geometry.safety_check(spec.env.safety)
    kinematics = safety.kinematics
    home = np.asarray(spec.robot.home, float)
    goal = spec.task.goal
    problems = []
    ee_goal = goal.achieved.partition(".")[0] == "ee"

    def solve(point):
        return kinematics.solve_ik(home, point)

    low, high = (np.asarray(b, float) for b in goal.box)
    # each part's goal is the goal moved by its offset: an object placed there must be carried there
    for part, offset in zip(goal.parts, goal.part_offsets):
        probes = [np.asarray(goal.static_goal, float)] if not goal.random else _probes(low, high)
        if not goal.within_reach:
            probes = []  # the object gets there on its own
        misses = []
        for point in probes:
            point = point + offset
            solution = solve(point)
            # an EE goal is sampled only where the arm can stand clear of the table; an object
            # goal is reached by the object, the EE only needs to get there
            if not solution.success:
                misses.append((point, f"IK misses by {solution.position_error:.3f} m"))
            elif ee_goal and not safety.pose_is_clear(solution.q_arm):
                misses.append((point, "the pose there comes too near the table or the arm itself"))
        if misses:
            where = "task.goal.static" if not goal.random and goal.static is not None else "task.goal.box"
            if part in goal.also:
                where = f"task.goal.also.{part}.offset"
            listed = "; ".join(f"{_point(point)} ({why})" for point, why in misses[:4])
            more = f"; and {len(misses) - 4} more" if len(misses) > 4 else ""
            what = (
                f"{len(misses)} of the {len(probes)} probe points of the goal box (centre and corners)"
                if goal.random
                else "the static goal"
            )
            if part in goal.also:
                what += f", moved by {part}'s offset {_point(offset)},"
            problems.append(
                (
                    where,
                    f"the arm cannot reach {what}: {listed}{more}; valid: a goal "
                    f"{'box whose every point is ' if goal.random else ''}within reach of robot "
                    f"{spec.robot.name!r}",
                )
            )
    for name, obj in spec.task.objects.items():
        position = np.asarray(obj.spawn.position, float)
        # a random spawn is drawn from position ± offset in x and y: its corners are probed too
        offset = np.array([*obj.spawn.offset, 0.0]) if obj.spawn.random else np.zeros(3)
        spots = [position] + (
            [position + offset * [sx, sy, 0.0] for sx in (-1, 1) for sy in (-1, 1)] if np.any(offset) else []
        )
        missed = [(spot, solution.position_error) for spot in spots if not (solution := solve(spot)).success]
        if missed:
            spot, error = missed[0]
            what = "its spawn point" if spot is position else "a corner of its spawn box (position ± offset)"
            problems.append(
                (
                    f"task.objects.{name}.spawn.position",
                    f"the arm cannot reach {name} at {what} {_point(spot)} (IK misses by {error:.3f} m"
                    f"{f'; {len(missed)} of {len(spots)} spawn probes missed' if len(missed) > 1 else ''})",
                )
            )
    return problems


def _held_turned(point, kinematics, safety, home: np.ndarray) -> list[tuple[str, str]]:
    """A point the expert holds with the gripper turned (any of its rotations will do): the arm must reach one
    of them, clear of the table and itself."""
    target, gripper = point.points[0], point.gripper[0]
    misses = []
    for rotation in point.rotations:
        solution = kinematics.solve_ik(home, target, target_rotation=rotation, gripper=gripper, rotation_weight=1.0)
        if not solution.success:
            misses.append(f"IK misses by {solution.position_error:.3f} m")
            continue
        verdict = safety.check(solution.q_arm, solution.q_arm, gripper)
        if verdict.accepted:
            return []
        misses.append(verdict.reason)
    return [
        (
            point.param,
            f"the arm cannot hold the object as the expert's '{point.name}' asks, at {_point(target)} "
            f"(either way round: {'; '.join(misses)})",
        )
    ]


def _expert_problems(spec: ComposedSpec, geometry: RobotGeometry) -> list[tuple[str, str]]:
    """The expert's grasp and push points must be poses the safety check accepts: a point where the fingers
    come within the safety margin of the table is refused at every try, and the expert stalls above it."""
    robot = spec.robot
    if robot.top_down_rpy is None:
        return []
    safety = geometry.safety_check(spec.env.safety)
    kinematics = safety.kinematics
    home = np.asarray(robot.home, float)
    _, home_rotation = kinematics.ee_pose(home, spec.gripper_assumed_at_reset)
    down = pin.rpy.rpyToMatrix(*robot.top_down_rpy)
    closing = "xyz".index(robot.gripper.closing_axis) if robot.gripper is not None else 1
    problems = []
    for point in expert_points(spec):
        if point.rotations is not None:
            problems += _held_turned(point, kinematics, safety, home)
            continue
        if point.name not in ("grasp", "push"):
            continue
        # the expert squares the fingers to the object (a quarter turn grips alike) or lays them across the push
        yaw, period = (
            (0.0, np.pi / 2)
            if point.direction is None
            else (float(np.arctan2(point.direction[1], point.direction[0])), np.pi)
        )
        rotation = nearest_top_down(down, home_rotation, closing, yaw, period)
        target = point.points[0]
        for gripper in point.gripper:
            solution = kinematics.solve_ik(home, target, target_rotation=rotation, gripper=gripper, rotation_weight=1.0)
            if not solution.success:
                problems.append(
                    (
                        point.param,
                        f"the arm cannot reach the expert's {point.name} point {_point(target)} "
                        f"with the gripper pointing down (IK misses by "
                        f"{solution.position_error:.3f} m)",
                    )
                )
                break
            verdict = safety.check(solution.q_arm, solution.q_arm, gripper)
            if not verdict.accepted:
                problems.append(
                    (
                        point.param,
                        f"the expert's {point.name} point {_point(target)} (the object's "
                        f"centre z {target[2] - point.offset:g} + {point.offset:g}) is a pose the "
                        f"safety check refuses ({verdict.reason}; the margin is "
                        f"{spec.env.safety.surface_margin:g} m) with the gripper at "
                        f"{gripper:g}: the expert can never get there; valid: a higher "
                        f"{point.param.rsplit('.', 1)[-1]}",
                    )
                )
                break
    return problems
