"""Observation terms of the task's objects: pose, finite-difference velocities, offset from the EE."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from envfactory.geometry.kinematics import quaternion_to_matrix
from envfactory.terms.goal_parts import TURN, GoalParts
from envfactory.terms.library import Description, TermParams, constant_bounds, fixed, observation_term
from envfactory.terms.observations import TWO_PI, box_bounds


class ObjectParams(TermParams):
    object: str


def bind_object(layout, params):
    # a fixture's reading is a pose as an object's is (its moving link's): the pose terms serve both
    known = [*layout.task.objects, *layout.task.fixtures]
    if params.object not in known:
        what = "object or fixture" if layout.task.fixtures else "object"
        raise ValueError(f"'object: {params.object}' names no {what} of the task (known: {known or 'none'})")
    return params


SOURCE = "object pose from the backend"
FINITE_DIFFERENCE = "finite difference over the step"


def _object_term(component: str, source: str, unit: str, bounds):
    return observation_term(
        size=fixed(3),
        bounds=bounds,
        describe=lambda layout, params: Description(
            component.format(Name=params.object.capitalize()), source.format(name=params.object), unit
        ),
        params=ObjectParams,
        bind=bind_object,
        unit=unit,
    )


def _relative_bounds(layout, params, size):
    # the object within its box, the EE within its own: the offset within the difference of the two
    ee, obj = layout.boxes.ee, layout.boxes.of(params.object)
    return obj.low - ee.high, obj.high - ee.low


def _linear_speed_bounds(layout, params, size):
    speed = layout.boxes.linear_speed(params.object)
    return -speed, speed


def _angular_speed_bounds(layout, params, size):
    return np.full(size, -layout.boxes.angular_speed), np.full(size, layout.boxes.angular_speed)


@_object_term("{Name} position", SOURCE, "m", lambda layout, params, size: box_bounds(layout.boxes.of(params.object)))
def object_position(state, params):
    """The object's position in the task frame (bounds: the arm's reach, the table and the floor)."""
    return state.objects[params.object].position


@_object_term("{Name} rpy", SOURCE, "rad", constant_bounds(-TWO_PI, TWO_PI))
def object_rpy(state, params):
    """The object's roll, pitch, yaw."""
    return state.objects[params.object].rpy


@_object_term("{Name} linear velocity (finite-diff)", FINITE_DIFFERENCE, "m/s", _linear_speed_bounds)
def object_linear_velocity(state, params):
    """The object's linear velocity, a finite difference over the step (bounds: the object box over a step)."""
    return state.objects[params.object].linear_velocity


@_object_term("{Name} angular velocity (finite-diff)", FINITE_DIFFERENCE, "rad/s", _angular_speed_bounds)
def object_angular_velocity(state, params):
    """The object's angular velocity, a finite difference over the step (bounds: a half turn over a step)."""
    return state.objects[params.object].angular_velocity


@_object_term("{Name} position relative to EE", "{name} − ee", "m", _relative_bounds)
def object_relative_to_ee(state, params):
    """The object's position minus the EE's (bounds: the object box minus the EE box)."""
    return state.objects[params.object].position - state.ee_position


@dataclass(frozen=True)
class OrientationGoal:
    """An orientation column's bound params: the object, and its goal quaternion's columns in the goal vector."""

    object: str
    start: int
    stop: int


def bind_orientation_goal(layout, params) -> OrientationGoal:
    bind_object(layout, params)
    turned = list(layout.task.goal.orientation)
    if params.object not in turned:
        raise ValueError(
            f"'object: {params.object}' has no orientation goal (task.goal.orientation: {turned or 'none'})"
        )
    start = GoalParts.of(layout.task.goal).points_size + TURN * turned.index(params.object)
    return OrientationGoal(params.object, start, start + TURN)


def _turn_to_goal(state, params) -> np.ndarray:
    goal = quaternion_to_matrix(state.current_goal[params.start : params.stop])
    return pin.log3(goal @ state.objects[params.object].rotation.T)


@observation_term(
    size=fixed(3),
    bounds=constant_bounds(-np.pi, np.pi),
    describe=lambda layout, params: Description(
        f"Rotation {params.object} → its goal orientation", "axis × angle, task frame", "rad"
    ),
    params=ObjectParams,
    goal_dependent=True,
    bind=bind_orientation_goal,
    unit="rad",
)
def goal_rotation(state, params):
    """The rotation (axis times angle, task frame) that turns the object into its goal orientation."""
    return _turn_to_goal(state, params)


@observation_term(
    size=fixed(1),
    bounds=constant_bounds(0.0, np.pi),
    describe=lambda layout, params: Description(
        f"Angle {params.object} → its goal orientation", "‖goal_rotation‖", "rad"
    ),
    params=ObjectParams,
    goal_dependent=True,
    bind=bind_orientation_goal,
    unit="rad",
)
def goal_angle(state, params):
    """The angle between the object's orientation and its goal orientation."""
    return np.array([np.linalg.norm(_turn_to_goal(state, params))])
