"""Where a task's scripted expert must put the EE: its grasp, push, approach and place points, read from the
expert's params (their own docs define them: grasp_height, height and clearance are EE heights above the
object's centre, lift the carry height above its spawn) and the task's spawn and goal boxes, in the task frame.

The checks of the workspace (`scene_checks`) and of reach and safety (`robot_checks`) judge these points, so an
expert that could never reach its grasp is refused before a single episode runs at 0%.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from envfactory.experts import EXPERTS
from envfactory.experts.pnp import APPROACH_WITHIN, GRASP_WITHIN, LIFT_WITHIN
from envfactory.experts.push import PUSH_WITHIN
from envfactory.schema.models import EnvSpec


@dataclass(frozen=True)
class ExpertPoint:
    name: str  # what the expert does there: "grasp", "push", ...
    param: str  # the dotted path of the param that sets its height
    points: np.ndarray  # (n, 3) task-frame EE positions: the point at the spawn centre first, then its corners
    offset: float  # the EE's height above the object's centre there
    gripper: tuple[float, ...]  # the gripper values the expert holds there
    # how near the EE must come for the expert to go on (the experts' own thresholds): an
    # EE held this far off by the workspace still does the job
    slack: float
    direction: np.ndarray | None = None  # the push direction (x, y) of a push point


def expert_points(spec: EnvSpec) -> list[ExpertPoint]:
    """The expert's working points, or [] without an expert (or with one whose params do not validate: the
    compiler reports those)."""
    ref = spec.task.expert
    if ref is None or ref.policy not in EXPERTS:
        return []
    try:
        params = EXPERTS[ref.policy].Params.model_validate(ref.params)
    except ValueError:
        return []
    name = getattr(params, "object", None)
    obj = spec.task.objects.get(name) if name is not None else None
    if obj is None:  # the reach expert works at the goal itself, which the goal checks cover
        return []
    gripper = spec.robot.gripper
    spawn = np.asarray(obj.spawn.position, float)
    offset = np.array([*obj.spawn.offset, 0.0]) if obj.spawn.random else np.zeros(3)
    spots = np.array([spawn] + [spawn + offset * [sx, sy, 0.0] for sx in (-1, 1) for sy in (-1, 1)])
    z = float(spawn[2])
    base = "task.expert.params"
    found = []
    if hasattr(params, "grasp_height"):
        grip = (gripper.closed if params.grip is None else params.grip) if gripper is not None else 0.0
        held = (gripper.open, grip) if gripper is not None else (0.0,)
        found.append(ExpertPoint("grasp", f"{base}.grasp_height", spots + [0, 0, params.grasp_height],
                                 params.grasp_height, held, GRASP_WITHIN))
        found += _place_points(spec, params, grip)
    if hasattr(params, "height") and hasattr(params, "paddle"):
        goal = np.mean(np.asarray(spec.task.goal.box, float), axis=0)
        direction = goal[:2] - spawn[:2]
        direction = direction / np.linalg.norm(direction) if np.linalg.norm(direction) > 1e-9 else np.array([1.0, 0])
        # behind the object on the line to the goal: the pushing face at half the object plus the paddle
        behind = spawn[:2] - direction * (obj.size / 2 + params.paddle)
        point = np.array([[*behind, z + params.height]])
        found.append(ExpertPoint("push", f"{base}.height", point, params.height, (spec.gripper_assumed_at_reset,),
                                 PUSH_WITHIN, direction))
    if hasattr(params, "clearance"):
        found.append(ExpertPoint("approach", f"{base}.clearance", spots + [0, 0, params.clearance],
                                 params.clearance, (), APPROACH_WITHIN))
    return found


def _place_points(spec: EnvSpec, params, grip: float) -> list[ExpertPoint]:
    """Pick-and-place lifts the object straight up by `lift`, then carries it with the EE grasp_height above its
    centre to the goal: the lift point over the spawn, and the goal box's corners raised by grasp_height."""
    goal = spec.task.goal
    if goal.achieved.partition(".")[0] != params.object:
        return []
    low, high = (np.asarray(b, float) for b in goal.box)
    corners = np.array([[x, y, z] for x in (low[0], high[0]) for y in (low[1], high[1]) for z in (low[2], high[2])])
    spawn = np.asarray(spec.task.objects[params.object].spawn.position, float)
    lifted = np.array([spawn + [0, 0, params.grasp_height + params.lift]])
    # placed when the object is within the goal's tolerance
    return [ExpertPoint("place", "task.goal.box", corners + [0, 0, params.grasp_height], params.grasp_height, (grip,),
                        goal.tolerance),
            ExpertPoint("lift", "task.expert.params.lift", lifted, params.grasp_height + params.lift, (grip,),
                        LIFT_WITHIN)]
