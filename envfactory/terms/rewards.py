"""Reward and termination terms, vectorised over a batch of goals.

Goal-derived terms compute from (achieved, desired) alone, so HER can
relabel them; the others read flags that the step recorded in `info`.
With a lift stage, the step also records the stage's goal while it lasts;
it does not derive from the desired goal, so relabelled rewards stay exact.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from envfactory.schema.errors import suggest
from envfactory.terms.goal_parts import GoalParts
from envfactory.terms.library import TermParams, UnknownReference, reward_term, termination_term
from envfactory.terms.stages import STAGE_KEYS

# Step info the env records at every step, declared here once: the step writes these keys
# and the terms below read them. A goal env's compute_reward(achieved, desired, info)
# needs the info the step returned; a missing key is an error, never a silent 0.
STEP_FLAGS = {
    "action_out_of_bounds": "1 if the action left the joint or workspace bounds, or its yaw turn was not made",
    "action_rejected": "1 if the safety check rejected the action",
    "goal_sampling_failed": "1 if no reachable goal was found at reset",
}


def step_info_keys() -> tuple[str, ...]:
    """The info keys every step of every env records for the reward terms."""
    return (*STEP_FLAGS, *STAGE_KEYS)


class PartChoice(TermParams):
    # one part of a goal of several ('task.goal.also'): its object's name; every part if unset
    object: str | None = None


class GoalChoice(PartChoice):
    # current: the lift stage's goal while it lasts, then the desired goal
    goal: Literal["current", "final"]


class CurrentGoal(GoalChoice):
    goal: Literal["current", "final"] = "current"


class FinalGoal(GoalChoice):
    goal: Literal["current", "final"] = "final"


@dataclass(frozen=True)
class GoalTarget:
    """A goal term's params bound to the task's goal parts: which goal, which part (None: every part) and the
    layout of the goal vectors."""

    goal: str
    part: int | None
    parts: GoalParts


def bind_part(layout, params) -> GoalTarget:
    return _bound(layout, params, layout.task.goal.parts, "goal")


def bind_turn(layout, params) -> GoalTarget:
    if not layout.task.goal.orientation:
        raise UnknownReference("the goal holds no orientation: declare task.goal.orientation")
    return _bound(layout, params, tuple(layout.task.goal.orientation), "orientation goal")


def _bound(layout, params, names: tuple[str, ...], what: str) -> GoalTarget:
    if params.object is not None and params.object not in names:
        raise UnknownReference(
            f"object {params.object!r} has no {what}; the {what}'s parts: {', '.join(names)}"
            f"{suggest(params.object, names)}"
        )
    part = None if params.object is None else names.index(params.object)
    return GoalTarget(getattr(params, "goal", "final"), part, GoalParts.of(layout.task.goal))


def _target(desired, info, params):
    if params.goal == "final":
        return desired
    active = np.asarray(info["intermediate_active"]) > 0
    if not active.ndim:  # one step's
        return info["intermediate_goal"] if active else desired
    if not active.any():
        return desired
    return np.where(active[..., None], info["intermediate_goal"], desired)


def _distances(achieved, desired, target: GoalTarget):
    """Each measured point part's distance to its goal, (..., parts): the bound part alone, or every one."""
    return target.parts.distances(achieved, desired, target.part)


def _angles(achieved, desired, target: GoalTarget):
    """Each measured orientation part's angle to its goal, (..., parts): the bound part alone, or every one."""
    return target.parts.angles(achieved, desired, target.part)


def _reached(achieved, desired, target: GoalTarget, tolerance):
    return target.parts.reached(achieved, desired, tolerance, target.part)


@reward_term(
    description="Σ over the goal's parts of ‖achieved − goal‖",
    params=CurrentGoal,
    info_keys=STAGE_KEYS,
    bind=bind_part,
)
def goal_distance(achieved, desired, info, params, tolerance):
    return _distances(achieved, _target(desired, info, params), params).sum(axis=-1)


@reward_term(
    description="1 if every part's ‖achieved − goal‖ < tolerance",
    params=FinalGoal,
    info_keys=STAGE_KEYS,
    bind=bind_part,
)
def goal_reached(achieved, desired, info, params, tolerance):
    return _reached(achieved, _target(desired, info, params), params, tolerance).astype(float)


@reward_term(description="0 if every part's ‖achieved − goal‖ < tolerance else -1", params=PartChoice, bind=bind_part)
def goal_reached_sparse(achieved, desired, info, params, tolerance):
    return _reached(achieved, desired, params, tolerance).astype(float) - 1.0


@reward_term(
    description="Σ over the goal's orientation parts of the angle to the goal, rad",
    params=PartChoice,
    bind=bind_turn,
)
def goal_angle(achieved, desired, info, params, tolerance):
    return _angles(achieved, desired, params).sum(axis=-1)


@reward_term(description="1 every step")
def constant(achieved, desired, info, params, tolerance):
    return np.ones(achieved.shape[:-1]) if achieved.ndim > 1 else 1.0  # one step's: a plain number


def _info_flag(key: str, description: str):
    def flag(achieved, desired, info, params, tolerance):
        return info[key]

    flag.__name__ = key
    return reward_term(description=description, info_keys=(key,))(flag)


for _key, _description in STEP_FLAGS.items():
    _info_flag(_key, _description)


@termination_term(
    name="goal_reached",
    description="every part's ‖achieved − goal‖ < tolerance",
    params=PartChoice,
    bind=bind_part,
)
def goal_reached_termination(achieved, desired, info, params, tolerance):
    return _reached(achieved, desired, params, tolerance)
