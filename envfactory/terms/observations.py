"""Observation terms. Each returns its slice of the observation vector."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydantic import ConfigDict, Field

from envfactory.geometry.point_boxes import Box
from envfactory.geometry.vectors import length
from envfactory.schema.numbers import TWO_PI
from envfactory.terms.goal_parts import POINT
from envfactory.terms.library import Description, TermParams, constant_bounds, fixed, observation_term, size_of


def box_bounds(box) -> tuple[np.ndarray, np.ndarray]:
    return box.low.copy(), box.high.copy()


def goal_box(layout, part: int = 0) -> Box:
    """Where a part's current goal can be: the goal box moved by the part's offset, and with a lift stage the
    lifted spawn points."""
    goal = layout.task.goal
    offset = goal.part_offsets[part]
    box = Box(*(np.asarray(b, float) + offset for b in goal.box))
    if goal.lift is not None:
        for obj in layout.task.objects.values():
            spawn = np.asarray(obj.spawn.position, float) + [0.0, 0.0, goal.lift.height]
            offset = np.array([*obj.spawn.offset, 0.0]) if obj.spawn.random else np.zeros(3)
            box = box.union(Box(spawn - offset, spawn + offset))
    return box


def goal_part(layout, name: str) -> int:
    """The goal part a point is measured against: its own goal if it has one, else the first part's."""
    parts = layout.task.goal.parts
    return parts.index(name) if name in parts else 0


def goal_distance_bounds(layout, params, size):
    # no farther than the farthest two points of the two boxes
    box = goal_box(layout, goal_part(layout, params.from_))
    return np.zeros(size), np.full(size, layout.boxes.of(params.from_).farthest_from(box))


joint_state_count = size_of("one per joint_states entry", lambda layout, params: len(layout.robot.joint_states))


class FromPoint(TermParams):
    # `from` is a Python keyword; YAML users write `from: cube`.
    model_config = ConfigDict(extra="forbid", frozen=True, populate_by_name=True)
    from_: str = Field(default="ee", alias="from")


def _point_label(name: str) -> str:
    return "EE" if name == "ee" else name


def _goal_label(layout, name: str) -> str:
    # with a lift stage the columns follow the stage's goal, as the reference pages name it
    goal = layout.task.goal
    if len(goal.parts) > 1:
        return f"{goal.parts[goal_part(layout, name)]}'s goal"
    return "current goal" if goal.lift is not None and goal.lift.enabled else "goal"


def _point_symbol(name: str) -> str:
    return "ee" if name == "ee" else name


def _bind_point(layout, params):
    if params.from_ != "ee" and params.from_ not in (*layout.task.objects, *layout.task.fixtures):
        known = ["ee", *layout.task.objects, *layout.task.fixtures]
        what = "object or fixture" if layout.task.fixtures else "object"
        raise ValueError(f"'from: {params.from_}' names no {what} of the task (known: {known})")
    part = goal_part(layout, params.from_)
    return GoalPoint(params.from_, POINT * part, POINT * (part + 1))


@dataclass(frozen=True)
class GoalPoint:
    """A goal column's bound params: the point it measures from, and its goal's columns in the goal vector."""

    from_: str
    start: int  # its goal's columns in the goal vector
    stop: int


def _joint_units(layout, per_second: bool) -> str:
    units = sorted({entry.unit for entry in layout.robot.joint_states}, key=["rad", "m"].index)
    suffix = "/s" if per_second else ""
    return " / ".join(unit + suffix for unit in units)


@observation_term(
    size=fixed(3),
    bounds=lambda layout, params, size: box_bounds(layout.boxes.ee),
    describe=lambda layout, params: Description("EE position", "Pinocchio FK", "m"),
    unit="m",
)
def ee_position(state, params):
    """EE position in the task frame (bounds: robot.ee_bounds grown to the arm's reach)."""
    return state.ee_position


@observation_term(
    size=fixed(3),
    bounds=constant_bounds(-TWO_PI, TWO_PI),
    describe=lambda layout, params: Description("EE rpy", "Pinocchio FK", "rad"),
    unit="rad",
)
def ee_rpy(state, params):
    """EE roll, pitch, yaw in the task frame."""
    return state.ee_rpy


@observation_term(
    size=fixed(3),
    bounds=constant_bounds(-1.0, 1.0),
    describe=lambda layout, params: Description(
        f"Unit vector {_point_label(params.from_)} → {_goal_label(layout, params.from_)}", "normalized", "unitless"
    ),
    params=FromPoint,
    goal_dependent=True,
    bind=_bind_point,
    unit="unitless",
)
def goal_direction(state, params):
    """Unit vector from the EE or an object to the current goal (its own, in a goal of several parts)."""
    offset = state.current_goal[params.start : params.stop] - state.position_of(params.from_)
    norm = length(offset)
    return offset / norm if norm > 1e-9 else np.zeros(3)


@observation_term(
    size=fixed(1),
    bounds=goal_distance_bounds,
    describe=lambda layout, params: Description(
        f"Euclidean distance {_point_label(params.from_)} → {_goal_label(layout, params.from_)}",
        f"‖goal − {_point_symbol(params.from_)}‖",
        "m",
    ),
    params=FromPoint,
    goal_dependent=True,
    bind=_bind_point,
    unit="m",
)
def goal_distance(state, params):
    """Distance from the EE or an object to the current goal (bound: the farthest it can be from the goal box)."""
    return length(state.current_goal[params.start : params.stop] - state.position_of(params.from_))


@observation_term(
    size=joint_state_count,
    bounds=lambda layout, params, size: box_bounds(layout.boxes.joint_positions),
    describe=lambda layout, params: Description(
        "Current joint positions", f"{layout.robot.joint_states_source}.position", _joint_units(layout, False)
    ),
    unit="rad or m per joint",
)
def joint_positions(state, params):
    """Joint positions in /joint_states order (bounds: robot.joint_states position, widened to the URDF's
    limits where those are wider)."""
    return state.joint_positions


@observation_term(
    size=size_of("the action size", lambda layout, params: layout.action_size),
    bounds=lambda layout, params, size: (layout.action_low.copy(), layout.action_high.copy()),
    describe=lambda layout, params: Description("Previous action", "cached", "matches action space"),
    unit="as the action",
)
def previous_action(state, params):
    """The action of the previous step (after clipping)."""
    return state.previous_action


@observation_term(
    size=joint_state_count,
    bounds=lambda layout, params, size: box_bounds(layout.boxes.joint_velocities),
    describe=lambda layout, params: Description(
        "Current joint velocities", f"{layout.robot.joint_states_source}.velocity", _joint_units(layout, True)
    ),
    unit="rad/s or m/s per joint",
)
def joint_velocities(state, params):
    """Joint velocities in /joint_states order (bounds: robot.joint_states velocity, widened to the URDF's
    velocity limits where those are wider)."""
    return state.joint_velocities
