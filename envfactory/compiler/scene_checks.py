"""Checks that join several parts of a spec: boxes inside the workspace, above the
table, objects resting on it, tolerances in proportion to the scene.

Everything here is geometry in the task frame and needs no URDF; what needs
the robot's kinematics lives in envfactory.compiler.robot_checks.
"""

from __future__ import annotations

import numpy as np

from envfactory.compiler.expert_points import expert_points
from envfactory.geometry.frames import TaskFrame
from envfactory.geometry.obstacles import table_bounds_xy
from envfactory.schema.models import ComposedSpec
from envfactory.schema.sources import Findings

# A goal tolerance above this fraction of the workspace diagonal makes "reached" meaningless.
TOLERANCE_FRACTION = 0.05
# How far an object's declared spawn height may sit from resting on the table top.
RESTING_SLACK = 0.01
# An object's goal is where the arm carries it from the table: a goal box reaching higher than this above the
# table top is a frame or unit mistake, not a task. The shipped pick-and-place goals reach 0.25 m; a world-frame
# height pasted into a base-frame robot on the cafe table lands near 0.8 m, which the reach check alone lets
# through on a tall arm while the expert never gets the object there.
MAX_OBJECT_GOAL_HEIGHT = 0.5
# Heights read in the other frame "sit on the table" when they land this close above its top: a goal or spawn
# point near the table is how both frames' boxes start.
NEAR_TABLE = 0.1
# A task frame whose origin is this far above or below the world's makes a height pasted from the other frame a
# mistake the table catches; closer, the frames' heights cannot be told apart.
FRAME_SHIFT_MIN = 0.1


def _fmt(values) -> str:
    return "[" + ", ".join(f"{float(v):g}" for v in values) + "]"


def _box(low, high) -> str:
    return f"[{_fmt(low)}, {_fmt(high)}]"


class TaskFrameScene:
    """The table and the floor in the task frame (which turns about z at most, so heights stay heights)."""

    def __init__(self, spec: ComposedSpec):
        self.frame = TaskFrame.of(spec.robot)
        origin = self.frame.origin
        table = spec.scene.table
        self.table_min, self.table_max = table_bounds_xy(table, self.frame)
        # a turned frame judges "inside the table" in the world, where the table is a box
        self._world_table = table_bounds_xy(table, TaskFrame(np.zeros(3)))
        self.top_z = table.top_z - origin[2]
        self.floor_z = spec.env.safety.floor_z - origin[2]

    def over_table(self, low_xy, high_xy) -> bool:
        return bool(np.all(np.asarray(low_xy) <= self.table_max) and np.all(np.asarray(high_xy) >= self.table_min))

    def inside_table(self, low_xy, high_xy) -> bool:
        """Whether the x/y box (task frame) lies within the table's footprint."""
        if not self.frame.rotated:
            return bool(np.all(np.asarray(low_xy) >= self.table_min) and np.all(np.asarray(high_xy) <= self.table_max))
        corners = np.array(
            [self.frame.to_world([x, y, 0.0])[:2] for x in (low_xy[0], high_xy[0]) for y in (low_xy[1], high_xy[1])]
        )
        low, high = self._world_table
        return bool(np.all(corners >= low) and np.all(corners <= high))

    def height(self, z: float) -> float:
        """Height above the table top of a task-frame z."""
        return float(z) - self.top_z

    def other_frame_hint(self, spec: ComposedSpec, low_z: float) -> str:
        """'; ... looks like <other>-frame heights ...' when a box starting at `low_z` would sit on the table read
        in the other frame (world heights in a base frame, or base heights in the world frame), else ''."""
        robot = spec.robot
        shift = float(robot.mount[2])  # the base frame's origin height in the world
        if abs(shift) < FRAME_SHIFT_MIN:
            return ""
        table_world = spec.scene.table.top_z
        if robot.task_frame == "base":
            # a world height w is w - shift in the base frame: read as world, does the box sit on the table?
            if -RESTING_SLACK <= low_z - table_world <= NEAR_TABLE:
                return (
                    f"; these look like world-frame heights: robot {robot.name!r} gives goals and spawns in its "
                    f"base frame (task_frame: base), whose origin is {shift:g} m up (robot.mount), so the table "
                    f"top is at z {self.top_z:g} there: subtract {shift:g} from every z"
                )
            return ""
        if -RESTING_SLACK <= low_z + shift - table_world <= NEAR_TABLE:
            return (
                f"; these look like base-frame heights: robot {robot.name!r} gives goals and spawns in the world "
                f"frame (task_frame: world), where its base is {shift:g} m up (robot.mount) and the table top at "
                f"z {table_world:g}: add {shift:g} to every z"
            )
        return ""

    def footprint(self) -> str:
        low, high = self._world_table if self.frame.rotated else (self.table_min, self.table_max)
        world = " (world frame)" if self.frame.rotated else ""
        return f"x in [{low[0]:g}, {high[0]:g}], y in [{low[1]:g}, {high[1]:g}]{world}"


def height_summary(spec: ComposedSpec) -> str:
    """The goal box's and each object's spawn height above the table top: what a frame or unit mistake in a
    height changes first, shown by describe and validate."""
    scene = TaskFrameScene(spec)
    low, high = (box[2] for box in spec.task.goal.box)
    parts = [f"goal {scene.height(low):.3f}–{scene.height(high):.3f} m"]
    parts += [
        f"{name} centre {scene.height(obj.spawn.position[2]):.3f} m (resting: {obj.half_extents[2]:g})"
        for name, obj in spec.task.objects.items()
    ]
    return f"Heights above the table top (z {scene.top_z:g} in the {spec.robot.task_frame} frame): " + ", ".join(parts)


def check_scene(spec: ComposedSpec, found: Findings) -> None:
    scene = TaskFrameScene(spec)
    _table(spec, scene, found)
    _goal(spec, scene, found)
    _objects(spec, scene, found)
    _spawns_apart(spec, found)
    _tolerance(spec, found)
    _observation_bounds(spec, found)


def _observation_bounds(spec: ComposedSpec, found: Findings) -> None:
    """The observation Box must hold what the robot can do: its workspace and its joint ranges."""
    robot = spec.robot
    ee_low, ee_high = robot.ee_bounds
    if any(lo < b for lo, b in zip(spec.workspace.min, ee_low)) or any(
        hi > b for hi, b in zip(spec.workspace.max, ee_high)
    ):
        found.add(
            "robot.ee_bounds",
            f"ee_bounds {_box(ee_low, ee_high)} must contain the workspace "
            f"{_box(spec.workspace.min, spec.workspace.max)}: the EE "
            f"observation would leave its Box",
        )
    index = {entry.urdf_joint: i for i, entry in enumerate(robot.joint_states)}
    needs = [
        (joint.name, (joint.lower, joint.upper), velocity)
        for joint, velocity in zip(robot.arm_joints, robot.arm_velocities)
    ]
    if robot.gripper is not None:
        needs.append((robot.gripper.joint, (robot.gripper.low, robot.gripper.high), robot.gripper.max_velocity))
    for name, (low, high), velocity in needs:
        i = index[name]
        entry = robot.joint_states[i]
        if entry.position[0] > low or entry.position[1] < high:
            found.add(
                f"robot.joint_states.{i}.position",
                f"position bounds {_fmt(entry.position)} of "
                f"{entry.name} must contain its commanded range "
                f"{_fmt((low, high))}",
            )
        if entry.velocity[0] > -velocity or entry.velocity[1] < velocity:
            found.add(
                f"robot.joint_states.{i}.velocity",
                f"velocity bounds {_fmt(entry.velocity)} of "
                f"{entry.name} must contain ±{velocity:g}, "
                f"the fastest it is driven",
            )


def _table(spec: ComposedSpec, scene: TaskFrameScene, found: Findings) -> None:
    table, floor = spec.scene.table, spec.env.safety.floor_z
    if table.top_z - table.thickness <= floor:
        found.add(
            "scene.table.top_z",
            f"the table top ({table.top_z:g} m, {table.thickness:g} m thick) must "
            f"stand above the floor (env.safety.floor_z = {floor:g})",
        )
    elif spec.robot.mount[2] < floor:
        found.add("robot.mount", f"the robot base z {spec.robot.mount[2]:g} lies below the floor ({floor:g})")


def _goal(spec: ComposedSpec, scene: TaskFrameScene, found: Findings) -> None:
    goal = spec.task.goal
    low, high = (np.asarray(b, float) for b in goal.box)
    for part, offset in zip(goal.parts, goal.part_offsets):
        path = f"task.goal.also.{part}.offset" if part in goal.also else "task.goal.box"
        _goal_part(spec, scene, found, low + offset, high + offset, part, path)


def _goal_part(spec, scene: TaskFrameScene, found: Findings, low, high, source: str, path: str) -> None:
    """One part's goal box (the goal box moved by the part's offset) against the workspace, the table and the
    heights an object is carried to."""
    workspace = spec.workspace
    ee_low, ee_high = (np.asarray(b, float) for b in spec.robot.ee_bounds)
    other_frame = scene.other_frame_hint(spec, low[2])
    if source == "ee":
        # the EE is only ever commanded inside the workspace, so a goal outside it is never reached
        bounds, name = (np.asarray(workspace.min, float), np.asarray(workspace.max, float)), "the workspace"
    else:
        bounds, name = (ee_low, ee_high), "robot.ee_bounds (the observation bounds)"
    outside = [axis for axis, lo, hi, b_lo, b_hi in zip("xyz", low, high, *bounds) if lo < b_lo or hi > b_hi]
    if outside:
        found.add(
            path,
            f"goal box {_box(low, high)} leaves {name} {_box(*bounds)} in "
            f"{', '.join(outside)}; valid: a box inside it{other_frame if 'z' in outside else ''}",
        )
    if source != "ee" and source in spec.task.objects and not scene.inside_table(low[:2], high[:2]):
        found.add(
            path,
            f"goal box x/y {_box(low[:2], high[:2])} leaves the table "
            f"({scene.footprint()}); {source} goals must lie over the table",
        )
    surface = scene.top_z if scene.over_table(low[:2], high[:2]) else scene.floor_z
    what = "table top" if surface == scene.top_z else "floor"
    where = f"(z {scene.top_z:g} in the {spec.robot.task_frame} frame)"
    if low[2] < surface:
        found.add(
            path,
            f"goal box bottom z {low[2]:g} lies below the {what} "
            f"(z {surface:g} in the {spec.robot.task_frame} frame); valid: z >= {surface:g}"
            f"{other_frame}",
        )
    elif other_frame and scene.height(low[2]) > abs(spec.robot.mount[2]) / 2:
        # nearer the table read in the other frame than in its own: a pasted height, wherever the arm reaches
        found.add(
            path,
            f"goal box bottom z {low[2]:g} lies {scene.height(low[2]):.3g} m above the table top {where}{other_frame}",
        )
    elif source != "ee" and scene.height(high[2]) > MAX_OBJECT_GOAL_HEIGHT:
        found.add(
            path,
            f"goal box top z {high[2]:g} lies {scene.height(high[2]):.3g} m above the table "
            f"top {where}: {source} is carried there from the table, and a goal more than "
            f"{MAX_OBJECT_GOAL_HEIGHT:g} m above it is out of any pick-and-place task; valid: "
            f"z <= {scene.top_z + MAX_OBJECT_GOAL_HEIGHT:.3g}",
        )


def _objects(spec: ComposedSpec, scene: TaskFrameScene, found: Findings) -> None:
    for name, obj in spec.task.objects.items():
        path = f"task.objects.{name}.spawn"
        position = np.asarray(obj.spawn.position, float)
        half, _, half_height = obj.half_extents
        lo, hi = _spawn_footprint(obj)
        if not scene.inside_table(lo, hi):
            found.add(
                f"{path}.position",
                f"{name} at x/y {_fmt(position[:2])} ± offset "
                f"{_fmt(obj.spawn.offset)} ± half its size {half:g} leaves "
                f"the table ({scene.footprint()})",
            )
        resting = scene.top_z + half_height
        if position[2] < resting - RESTING_SLACK:
            found.add(
                f"{path}.position",
                f"{name} centre z {position[2]:g} puts it inside the table: "
                f"resting on the top it is at z {resting:g}"
                f"{scene.other_frame_hint(spec, position[2] - half_height)}",
            )
        elif position[2] > resting + RESTING_SLACK:
            found.add(
                f"{path}.position",
                f"{name} centre z {position[2]:g} floats {position[2] - resting:.3g} m above "
                f"the table: resting on the top it is at z {resting:g}"
                f"{scene.other_frame_hint(spec, position[2] - half_height)}",
            )
        lift = spec.task.goal.lift
        if (
            lift is not None
            and spec.task.goal.achieved == f"{name}.position"
            and position[2] + lift.height > spec.workspace.max[2]
        ):
            found.add(
                "task.goal.lift.height",
                f"lifting {name} by {lift.height:g} m reaches z "
                f"{position[2] + lift.height:g}, above the workspace "
                f"(max z {spec.workspace.max[2]:g})",
            )


def _spawn_footprint(obj) -> tuple[np.ndarray, np.ndarray]:
    """Where an object may stand, in x and y: its spawn point ± the random offset ± half its size."""
    position = np.asarray(obj.spawn.position[:2], float)
    reach = np.asarray(obj.spawn.offset if obj.spawn.random else (0.0, 0.0)) + obj.half_extents[0]
    return position - reach, position + reach


def _spawns_apart(spec: ComposedSpec, found: Findings) -> None:
    """Objects are spawned each on its own: two whose spawn regions meet could be spawned inside each other."""
    placed = []
    for name, obj in spec.task.objects.items():
        low, high = _spawn_footprint(obj)
        for other, (other_low, other_high) in placed:
            if np.all(low < other_high) and np.all(other_low < high):
                found.add(
                    f"task.objects.{name}.spawn",
                    f"{name} may stand at x/y {_box(low, high)} and {other} at {_box(other_low, other_high)}: "
                    "they could be spawned inside each other; valid: spawn points farther apart, or smaller "
                    "offsets",
                )
        placed.append((name, (low, high)))


def check_expert_workspace(spec: ComposedSpec, found: Findings) -> None:
    """EE mode never commands the EE outside the workspace: an expert point out of it is never reached there.
    (Run with the compiler's checks, once the expert's params are known to be valid.)"""
    low, high = (np.asarray(bound, float) for bound in (spec.workspace.min, spec.workspace.max))
    for point in expert_points(spec):
        for axis, name in enumerate("xyz"):
            values = point.points[:, axis]
            if values.min() < low[axis] - point.slack:
                bound, edge, value = (
                    "min",
                    "below the workspace floor" if name == "z" else f"below its min {name}",
                    values.min(),
                )
            elif values.max() > high[axis] + point.slack:
                bound, edge, value = (
                    "max",
                    "above the workspace ceiling" if name == "z" else f"above its max {name}",
                    values.max(),
                )
            else:
                continue
            limit = (low if bound == "min" else high)[axis]
            height = f" (the object's centre z {value - point.offset:g} + {point.offset:g})" if name == "z" else ""
            found.add(
                f"workspace.{bound}",
                f"the expert's {point.name} point {name} {value:.3g}{height} lies {edge} "
                f"(workspace.{bound} {name} {limit:g}) by more than the {point.slack * 1000:g} mm "
                f"the expert allows: in EE mode (ee_action_type) the EE is never commanded "
                f"outside the workspace, so the expert never gets there; "
                f"valid: a workspace holding it, or another {found.where(point.param)}",
            )
            break


def _tolerance(spec: ComposedSpec, found: Findings) -> None:
    diagonal = float(np.linalg.norm(np.subtract(spec.workspace.max, spec.workspace.min)))
    limit = TOLERANCE_FRACTION * diagonal
    tolerance = spec.task.goal.tolerance
    if tolerance > limit:
        found.add(
            "task.goal.tolerance",
            f"tolerance {tolerance:g} m is implausible for this workspace: valid "
            f"up to {limit:.3f} m ({TOLERANCE_FRACTION:.0%} of its "
            f"{diagonal:.2f} m diagonal)",
        )
