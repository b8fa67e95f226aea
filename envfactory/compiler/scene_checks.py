"""Checks that join several parts of a spec: boxes inside the workspace, above the
table, objects resting on it, tolerances in proportion to the scene.

Everything here is geometry in the task frame and needs no URDF; what needs
the robot's kinematics lives in envfactory.compiler.robot_checks.
"""

from __future__ import annotations

import numpy as np

from envfactory.geometry.frames import TaskFrame
from envfactory.geometry.obstacles import table_bounds_xy
from envfactory.schema.models import EnvSpec
from envfactory.schema.sources import Findings

# A goal tolerance above this fraction of the workspace diagonal makes "reached" meaningless.
TOLERANCE_FRACTION = 0.05
# How far an object's declared spawn height may sit from resting on the table top.
RESTING_SLACK = 0.01



def _fmt(values) -> str:
    return "[" + ", ".join(f"{float(v):g}" for v in values) + "]"


def _box(low, high) -> str:
    return f"[{_fmt(low)}, {_fmt(high)}]"


class TaskFrameScene:
    """The table and the floor in the task frame (which turns about z at most, so heights stay heights)."""

    def __init__(self, spec: EnvSpec):
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
        corners = np.array([self.frame.to_world([x, y, 0.0])[:2] for x in (low_xy[0], high_xy[0])
                            for y in (low_xy[1], high_xy[1])])
        low, high = self._world_table
        return bool(np.all(corners >= low) and np.all(corners <= high))

    def footprint(self) -> str:
        low, high = self._world_table if self.frame.rotated else (self.table_min, self.table_max)
        world = " (world frame)" if self.frame.rotated else ""
        return f"x in [{low[0]:g}, {high[0]:g}], y in [{low[1]:g}, {high[1]:g}]{world}"


def check_scene(spec: EnvSpec, found: Findings) -> None:
    scene = TaskFrameScene(spec)
    _table(spec, scene, found)
    _goal(spec, scene, found)
    _objects(spec, scene, found)
    _tolerance(spec, found)
    _observation_bounds(spec, found)


def _observation_bounds(spec: EnvSpec, found: Findings) -> None:
    """The observation Box must hold what the robot can do: its workspace and its joint ranges."""
    robot = spec.robot
    ee_low, ee_high = robot.ee_bounds
    if any(lo < b for lo, b in zip(spec.workspace.min, ee_low)) or \
            any(hi > b for hi, b in zip(spec.workspace.max, ee_high)):
        found.add("robot.ee_bounds", f"ee_bounds {_box(ee_low, ee_high)} must contain the workspace "
                                     f"{_box(spec.workspace.min, spec.workspace.max)}: the EE "
                                     f"observation would leave its Box")
    index = {entry.urdf_joint: i for i, entry in enumerate(robot.joint_states)}
    needs = [(joint.name, (joint.lower, joint.upper), velocity)
             for joint, velocity in zip(robot.arm_joints, robot.arm_velocities)]
    if robot.gripper is not None:
        needs.append((robot.gripper.joint, (robot.gripper.low, robot.gripper.high), robot.gripper.max_velocity))
    for name, (low, high), velocity in needs:
        i = index[name]
        entry = robot.joint_states[i]
        if entry.position[0] > low or entry.position[1] < high:
            found.add(f"robot.joint_states.{i}.position", f"position bounds {_fmt(entry.position)} of "
                                                          f"{entry.name} must contain its commanded range "
                                                          f"{_fmt((low, high))}")
        if entry.velocity[0] > -velocity or entry.velocity[1] < velocity:
            found.add(f"robot.joint_states.{i}.velocity", f"velocity bounds {_fmt(entry.velocity)} of "
                                                          f"{entry.name} must contain ±{velocity:g}, "
                                                          f"the fastest it is driven")


def _table(spec: EnvSpec, scene: TaskFrameScene, found: Findings) -> None:
    table, floor = spec.scene.table, spec.env.safety.floor_z
    if table.top_z - table.thickness <= floor:
        found.add("scene.table.top_z", f"the table top ({table.top_z:g} m, {table.thickness:g} m thick) must "
                                       f"stand above the floor (env.safety.floor_z = {floor:g})")
    elif spec.robot.mount[2] < floor:
        found.add("robot.mount", f"the robot base z {spec.robot.mount[2]:g} lies below the floor ({floor:g})")


def _goal(spec: EnvSpec, scene: TaskFrameScene, found: Findings) -> None:
    goal, workspace = spec.task.goal, spec.workspace
    low, high = (np.asarray(b, float) for b in goal.box)
    source = goal.achieved.partition(".")[0]
    ee_low, ee_high = (np.asarray(b, float) for b in spec.robot.ee_bounds)
    if source == "ee":
        # the EE is only ever commanded inside the workspace, so a goal outside it is never reached
        bounds, name = (np.asarray(workspace.min, float), np.asarray(workspace.max, float)), "the workspace"
    else:
        bounds, name = (ee_low, ee_high), "robot.ee_bounds (the observation bounds)"
    outside = [axis for axis, lo, hi, b_lo, b_hi in zip("xyz", low, high, *bounds) if lo < b_lo or hi > b_hi]
    if outside:
        found.add("task.goal.box", f"goal box {_box(low, high)} leaves {name} {_box(*bounds)} in "
                                   f"{', '.join(outside)}; valid: a box inside it")
    if source != "ee" and source in spec.task.objects and not scene.inside_table(low[:2], high[:2]):
        found.add("task.goal.box", f"goal box x/y {_box(low[:2], high[:2])} leaves the table "
                                   f"({scene.footprint()}); {source} goals must lie over the table")
    surface = scene.top_z if scene.over_table(low[:2], high[:2]) else scene.floor_z
    what = "table top" if surface == scene.top_z else "floor"
    if low[2] < surface:
        found.add("task.goal.box", f"goal box bottom z {low[2]:g} lies below the {what} "
                                   f"(z {surface:g} in the {spec.robot.task_frame} frame); valid: z >= {surface:g}")


def _objects(spec: EnvSpec, scene: TaskFrameScene, found: Findings) -> None:
    for name, obj in spec.task.objects.items():
        path = f"task.objects.{name}.spawn"
        position = np.asarray(obj.spawn.position, float)
        half = obj.size / 2
        reach = np.asarray(obj.spawn.offset if obj.spawn.random else (0.0, 0.0)) + half
        lo, hi = position[:2] - reach, position[:2] + reach
        if not scene.inside_table(lo, hi):
            found.add(f"{path}.position", f"{name} at x/y {_fmt(position[:2])} ± offset "
                                          f"{_fmt(obj.spawn.offset)} ± half its size {half:g} leaves "
                                          f"the table ({scene.footprint()})")
        resting = scene.top_z + half
        if position[2] < resting - RESTING_SLACK:
            found.add(f"{path}.position", f"{name} centre z {position[2]:g} puts it inside the table: "
                                          f"resting on the top it is at z {resting:g}")
        elif position[2] > resting + RESTING_SLACK:
            found.add(f"{path}.position", f"{name} centre z {position[2]:g} floats above the table: "
                                          f"resting on the top it is at z {resting:g}")
        lift = spec.task.goal.lift
        if lift is not None and spec.task.goal.achieved == f"{name}.position" and \
                position[2] + lift.height > spec.workspace.max[2]:
            found.add("task.goal.lift.height", f"lifting {name} by {lift.height:g} m reaches z "
                                               f"{position[2] + lift.height:g}, above the workspace "
                                               f"(max z {spec.workspace.max[2]:g})")


def _tolerance(spec: EnvSpec, found: Findings) -> None:
    diagonal = float(np.linalg.norm(np.subtract(spec.workspace.max, spec.workspace.min)))
    limit = TOLERANCE_FRACTION * diagonal
    tolerance = spec.task.goal.tolerance
    if tolerance > limit:
        found.add("task.goal.tolerance", f"tolerance {tolerance:g} m is implausible for this workspace: valid "
                                         f"up to {limit:.3f} m ({TOLERANCE_FRACTION:.0%} of its "
                                         f"{diagonal:.2f} m diagonal)")
