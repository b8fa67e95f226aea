"""The term tables: every observation, reward and termination term by name.

A term is a plain function plus what the compiler needs to know without
running physics: its size, its Box bounds, how it reads in a table, and a
params model that rejects unknown or ill-typed params.
"""

from __future__ import annotations

import functools
import importlib
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np
from pydantic import BaseModel, ConfigDict


class UnknownReference(ValueError):
    """A term's params name something the task or robot lacks (an object, an observation term, a gripper)."""


class TermParams(BaseModel):
    """Params of a term or an expert: unknown keys are errors."""

    model_config = ConfigDict(extra="forbid", frozen=True)


NoParams = TermParams


@dataclass(frozen=True)
class TermContext:
    """Compile-time facts a term may need: the robot, the task and the action."""

    robot: Any
    task: Any
    action_size: int
    action_low: np.ndarray
    action_high: np.ndarray
    boxes: Any = None  # envfactory.geometry.point_boxes.PointBoxes: where the EE and each object can be
    observation_slots: tuple = ()  # the compiled observation layout, for sensing terms (after it is laid out)
    episode_steps: int = 100  # the ID's max_episode_steps: how long a drifting sensor drifts
    fixtures: Any = None  # {name: envfactory.geometry.fixtures.FixtureModel}: the task's fixtures as read


@dataclass(frozen=True)
class Description:
    component: str
    source: str
    unit: str


def unchanged(layout: "TermContext", params: Any) -> Any:
    return params


class RegisteredTerm:
    """A term pickles as its registered name (and the module that registers it), never as its
    callables: sizes, bounds and descriptions are often lambdas or closures, and a copy of a
    blueprint must use the very term the registry holds."""

    kind = ""  # the table it is registered in

    def __post_init__(self):
        # The registered term stands for its function: whoever holds the term (help(),
        # inspect.unwrap, a user browsing OBSERVATIONS) sees the function's name and docstring,
        # not the term class's. Frozen dataclasses refuse setattr, hence object.__setattr__
        # where functools.update_wrapper would use setattr.
        for attribute in functools.WRAPPER_ASSIGNMENTS:
            if hasattr(self.fn, attribute):
                object.__setattr__(self, attribute, getattr(self.fn, attribute))
        object.__setattr__(self, "__wrapped__", self.fn)

    def __reduce__(self):
        return registered_term, (self.kind, self.name, getattr(self.fn, "__module__", None))


def registered_term(kind: str, name: str, module: str | None):
    table = _TABLES[kind]
    if name not in table and module:
        importlib.import_module(module)  # a user's term module this process has not imported yet
    try:
        return table[name]
    except KeyError:
        raise KeyError(f"cannot unpickle {kind} term {name!r}: no module registers it here") from None


@dataclass(frozen=True)
class ObservationTerm(RegisteredTerm):
    kind = "observation"
    name: str
    fn: Callable  # (state, bound params) -> array of `size`
    size: Callable[[TermContext, Any], int]
    bounds: Callable[[TermContext, Any, int], tuple[np.ndarray, np.ndarray]]
    describe: Callable[[TermContext, Any], Description]
    params: type[BaseModel] = NoParams
    goal_dependent: bool = False
    # Checks the params against the robot and task (ValueError names what is
    # wrong) and returns what `fn` receives, with robot facts resolved once.
    bind: Callable[[TermContext, Any], Any] = unchanged
    unit: str = ""  # for `envfactory terms`; the describe table gives the resolved one

    @property
    def size_doc(self) -> str:
        return getattr(self.size, "doc", "depends on the robot")


@dataclass(frozen=True)
class GoalTerm(RegisteredTerm):
    """Pure in the goals and the step's info, vectorised over a batch:
    fn(achieved, desired, info, bound params, tolerance) -> (N,), so HER can relabel it."""

    name: str
    fn: Callable
    description: str
    params: type[BaseModel] = NoParams
    info_keys: tuple[str, ...] = ()  # step info the term reads
    bind: Callable[[TermContext, Any], Any] = unchanged


@dataclass(frozen=True)
class RewardTerm(GoalTerm):
    """A reward: fn returns (N,) floats, weighted in the task.

    A term that depends on the env state rather than the goals has `measure`:
    the step evaluates it on the state and records it in info under
    `info_keys[0]`, so `fn` (reading info) stays exact when HER relabels goals.
    """

    kind = "reward"
    measure: Callable[[Any, Any], float] | None = None


@dataclass(frozen=True)
class ImageTerm(RegisteredTerm):
    """fn(camera frame) -> array of `shape(camera)`; one Dict observation key per term."""

    kind = "image"
    name: str
    fn: Callable
    shape: Callable[[Any], tuple[int, ...]]
    dtype: type
    bounds: Callable[[Any], tuple[float, float]]
    description: str


@dataclass(frozen=True)
class TerminationTerm(GoalTerm):
    """Ends the episode: fn returns (N,) bools; a goal env's compute_terminated stays exact
    under relabelling."""

    kind = "termination"


@dataclass(frozen=True)
class EventTerm(RegisteredTerm):
    """Samples one physical quantity for the backend to set: fn(rng, bound params) -> PhysicsChange."""

    kind = "event"
    name: str
    fn: Callable
    params: type[BaseModel]
    bind: Callable[[TermContext, Any], Any]  # checks the range against the spec and resolves it to absolute values
    unit: str = ""


@dataclass(frozen=True)
class SensingTerm(RegisteredTerm):
    """Makes one env's sensor (envfactory.terms.sensing.Sensor): fn(bound params) -> Sensor."""

    kind = "sensing"
    name: str
    fn: Callable
    params: type[BaseModel]
    bind: Callable[[TermContext, Any], Any] = unchanged
    unit: str = ""


OBSERVATIONS: dict[str, ObservationTerm] = {}
IMAGES: dict[str, ImageTerm] = {}
REWARDS: dict[str, RewardTerm] = {}
TERMINATIONS: dict[str, TerminationTerm] = {}
EVENTS: dict[str, EventTerm] = {}
SENSING: dict[str, SensingTerm] = {}
_TABLES = {
    "observation": OBSERVATIONS,
    "image": IMAGES,
    "reward": REWARDS,
    "termination": TERMINATIONS,
    "event": EVENTS,
    "sensing": SENSING,
}


def term_decorator(term_class: type[RegisteredTerm], **spec) -> Callable:
    """A decorator registering the function as a `term_class` term built from `spec`, named
    `spec["name"]` or else after the function; the function itself comes back unchanged."""

    def register(fn):
        term = term_class(**{"name": fn.__name__, **spec}, fn=fn)
        table = _TABLES[term_class.kind]
        if term.name in table:
            raise ValueError(f"term {term.name!r} is registered twice")
        table[term.name] = term
        return fn

    return register


def observation_term(**spec) -> Callable:
    """Registers the decorated function as an ObservationTerm; `spec` holds its other fields."""
    return term_decorator(ObservationTerm, **spec)


def image_term(**spec) -> Callable:
    """Registers the decorated function as an ImageTerm; `spec` holds its other fields."""
    return term_decorator(ImageTerm, **spec)


def reward_term(**spec) -> Callable:
    """Registers the decorated function as a RewardTerm; `spec` holds its other fields."""
    return term_decorator(RewardTerm, **spec)


def termination_term(**spec) -> Callable:
    """Registers the decorated function as a TerminationTerm; `spec` holds its other fields."""
    return term_decorator(TerminationTerm, **spec)


def event_term(**spec) -> Callable:
    """Registers the decorated function as an EventTerm; `spec` holds its other fields."""
    return term_decorator(EventTerm, **spec)


def sensing_term(**spec) -> Callable:
    """Registers the decorated function as a SensingTerm; `spec` holds its other fields."""
    return term_decorator(SensingTerm, **spec)


def fixed(size: int) -> Callable[[TermContext, Any], int]:
    def sized(layout, params):
        return size

    sized.doc = str(size)
    return sized


def size_of(doc: str, function: Callable[[TermContext, Any], int]) -> Callable[[TermContext, Any], int]:
    """A size that depends on the robot or the action, with the words `envfactory terms` shows."""
    function.doc = doc
    return function


def constant_bounds(low, high) -> Callable:
    def bounds(layout, params, size):
        return np.broadcast_to(np.asarray(low, float), (size,)).copy(), np.broadcast_to(
            np.asarray(high, float), (size,)
        ).copy()

    return bounds
