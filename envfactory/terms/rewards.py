"""Reward and termination terms, vectorised over a batch of goals.

Goal-derived terms compute from (achieved, desired) alone, so HER can
relabel them; the others read flags that the step recorded in `info`.
With a lift stage, the step also records the stage's goal while it lasts;
it does not derive from the desired goal, so relabelled rewards stay exact.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from envfactory.geometry.vectors import lengths
from envfactory.terms.library import TermParams, reward_term, termination_term
from envfactory.terms.stages import STAGE_KEYS

# Step info the env records at every step, declared here once: the step writes these keys
# and the terms below read them. A goal env's compute_reward(achieved, desired, info)
# needs the info the step returned; a missing key is an error, never a silent 0.
STEP_FLAGS = {
    "action_out_of_bounds": "1 if the action left the joint or workspace bounds",
    "action_rejected": "1 if the safety check rejected the action",
    "goal_sampling_failed": "1 if no reachable goal was found at reset",
}


def step_info_keys() -> tuple[str, ...]:
    """The info keys every step of every env records for the reward terms."""
    return (*STEP_FLAGS, *STAGE_KEYS)


class GoalChoice(TermParams):
    # current: the lift stage's goal while it lasts, then the desired goal
    goal: Literal["current", "final"]


class CurrentGoal(GoalChoice):
    goal: Literal["current", "final"] = "current"


class FinalGoal(GoalChoice):
    goal: Literal["current", "final"] = "final"


def _target(desired, info, params):
    if params.goal == "final":
        return desired
    active = np.asarray(info["intermediate_active"]) > 0
    if not active.ndim:  # one step's
        return info["intermediate_goal"] if active else desired
    if not active.any():
        return desired
    return np.where(active[..., None], info["intermediate_goal"], desired)


def _distance(achieved, desired):
    return lengths(achieved - desired)


@reward_term(description="‖achieved − goal‖", params=CurrentGoal, info_keys=STAGE_KEYS)
def goal_distance(achieved, desired, info, params, tolerance):
    return _distance(achieved, _target(desired, info, params))


@reward_term(description="1 if ‖achieved − goal‖ < tolerance", params=FinalGoal, info_keys=STAGE_KEYS)
def goal_reached(achieved, desired, info, params, tolerance):
    return (_distance(achieved, _target(desired, info, params)) < tolerance).astype(float)


@reward_term(description="0 if ‖achieved − goal‖ < tolerance else -1")
def goal_reached_sparse(achieved, desired, info, params, tolerance):
    return (_distance(achieved, desired) < tolerance).astype(float) - 1.0


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


@termination_term(name="goal_reached", description="‖achieved − goal‖ < tolerance")
def goal_reached_termination(achieved, desired, info, params, tolerance):
    return _distance(achieved, desired) < tolerance
