"""Observation terms of the task's objects: pose, finite-difference velocities, offset from the EE."""

from __future__ import annotations

import numpy as np

from envfactory.terms.library import Description, TermParams, constant_bounds, fixed, observation_term
from envfactory.terms.observations import TWO_PI, ee_extent


class ObjectParams(TermParams):
    object: str


def bind_object(layout, params):
    if params.object not in layout.task.objects:
        known = list(layout.task.objects) or "none"
        raise ValueError(f"'object: {params.object}' names no object of the task (known: {known})")
    return params


SOURCE = "object pose from the backend"
FINITE_DIFFERENCE = "finite difference over the step"


def _object_term(component: str, source: str, unit: str, bounds):
    return observation_term(
        size=fixed(3),
        bounds=bounds,
        describe=lambda layout, params: Description(
            component.format(Name=params.object.capitalize()), source.format(name=params.object), unit),
        params=ObjectParams,
        bind=bind_object,
        unit=unit,
    )


def _relative_bounds(layout, params, size):
    # an object and the EE both lie within the EE bounds: their offset within ± the extent
    extent = ee_extent(layout)
    return -extent, extent


@_object_term("{Name} position", SOURCE, "m",
              lambda layout, params, size: tuple(np.array(b, float) for b in layout.robot.ee_bounds))
def object_position(state, params):
    """The object's position in the task frame (bounds: robot.ee_bounds)."""
    return state.objects[params.object].position


@_object_term("{Name} rpy", SOURCE, "rad", constant_bounds(-TWO_PI, TWO_PI))
def object_rpy(state, params):
    """The object's roll, pitch, yaw."""
    return state.objects[params.object].rpy


@_object_term("{Name} linear velocity (finite-diff)", FINITE_DIFFERENCE, "m/s", constant_bounds(-2.0, 2.0))
def object_linear_velocity(state, params):
    """The object's linear velocity, a finite difference over the step."""
    return state.objects[params.object].linear_velocity


@_object_term("{Name} angular velocity (finite-diff)", FINITE_DIFFERENCE, "rad/s", constant_bounds(-20.0, 20.0))
def object_angular_velocity(state, params):
    """The object's angular velocity, a finite difference over the step."""
    return state.objects[params.object].angular_velocity


@_object_term("{Name} position relative to EE", "{name} − ee", "m", _relative_bounds)
def object_relative_to_ee(state, params):
    """The object's position minus the EE's (bounds: ± the ee_bounds extent)."""
    return state.objects[params.object].position - state.ee_position
