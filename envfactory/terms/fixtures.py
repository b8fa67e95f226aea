"""Observation terms of the task's fixtures (task.fixtures): their joint, as the goal and the policy read it."""

from __future__ import annotations

import numpy as np

from envfactory.geometry.point_boxes import JOINT_STOP_SOFTNESS
from envfactory.terms.library import Description, TermParams, fixed, observation_term


class FixtureParams(TermParams):
    fixture: str


def bind_fixture(layout, params):
    if params.fixture not in layout.task.fixtures:
        known = list(layout.task.fixtures) or "none"
        raise ValueError(f"'fixture: {params.fixture}' names no fixture of the task (known: {known})")
    if not layout.fixtures or params.fixture not in layout.fixtures:
        # its URDF did not read: that problem is reported at task.fixtures, the bounds cannot be known
        raise ValueError(f"fixture {params.fixture!r} did not load (see task.fixtures.{params.fixture})")
    return params


def _travel(layout, params) -> float:
    fixture = layout.fixtures[params.fixture]
    return fixture.upper - fixture.lower


@observation_term(
    size=fixed(1),
    bounds=lambda layout, params, size: (
        np.array([-JOINT_STOP_SOFTNESS]),
        np.array([_travel(layout, params) + JOINT_STOP_SOFTNESS]),
    ),
    describe=lambda layout, params: Description(
        f"{params.fixture.capitalize()} joint ({layout.task.fixtures[params.fixture].joint})",
        "past its lower limit (a drawer: how far open)",
        "m",
    ),
    params=FixtureParams,
    bind=bind_fixture,
    unit="m",
)
def fixture_joint(state, params):
    """The fixture's joint past its lower limit: how far a drawer is open (bounds: the URDF's travel)."""
    return np.array([state.objects[params.fixture].joint])


@observation_term(
    size=fixed(1),
    bounds=lambda layout, params, size: (
        np.array([-_travel(layout, params) / layout.boxes.step_seconds]),
        np.array([_travel(layout, params) / layout.boxes.step_seconds]),
    ),
    describe=lambda layout, params: Description(
        f"{params.fixture.capitalize()} joint velocity (finite-diff)", "finite difference over the step", "m/s"
    ),
    params=FixtureParams,
    bind=bind_fixture,
    unit="m/s",
)
def fixture_joint_velocity(state, params):
    """The fixture joint's velocity, a finite difference over the step (bounds: its whole travel in one step)."""
    return np.array([state.objects[params.fixture].joint_velocity])
