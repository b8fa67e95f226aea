"""The task: objects, goal, observation layout, rewards, terminations and expert."""

from __future__ import annotations

from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from envfactory.schema.base import Model, Position, Rgba, in_unit_range, located
from envfactory.schema.numbers import Friction, NonNegative, Positive, Real
from envfactory.schema.randomization import RandomizationSpec


class TermRef(Model):
    """A reward term by name, its params and its weight."""

    term: str
    weight: Real = 1.0
    params: dict[str, Any] = {}


class SpawnSpec(Model):
    position: Position  # the object's centre at rest, task frame
    random: bool = True  # random_cube_spawn
    offset: tuple[Annotated[NonNegative, Field(le=1.0)], Annotated[NonNegative, Field(le=1.0)]] = (
        0.05,
        0.05,
    )  # random_offset: ± metres in x and y


class ObjectSpec(Model):
    shape: Literal["box", "cylinder"] = "box"  # a cube, or an upright cylinder (a puck)
    size: Annotated[Positive, Field(le=1.0)]  # a cube's edge or a cylinder's diameter, m: something a gripper handles
    height: Annotated[Positive, Field(le=1.0)] | None = None  # a cylinder's height, m; its diameter if unset
    rgba: Rgba = (1.0, 0.0, 0.0, 1.0)
    mass: Annotated[Positive, Field(le=100.0)]  # kg
    friction: Friction = 1.0
    spinning_friction: Friction = 0.0
    rolling_friction: Friction = 0.0
    spawn: SpawnSpec

    @model_validator(mode="after")
    def _colour(self) -> "ObjectSpec":
        in_unit_range(self.rgba)
        if self.shape == "box" and self.height is not None:
            raise located("height", "a box is a cube of edge 'size': 'height' is a cylinder's")
        return self

    @property
    def half_extents(self) -> tuple[float, float, float]:
        """Half the object's bounding box, upright: what the scene checks, spawns and the safety proofs use
        (for a cylinder, the box around it: larger, so still safe)."""
        radius = self.size / 2
        return (radius, radius, (self.height if self.height is not None else self.size) / 2)

    @property
    def bounding_radius(self) -> float:
        """The radius of the sphere around the object: what the motion proofs keep the robot away from."""
        if self.shape == "cylinder":
            return float(np.hypot(self.half_extents[0], self.half_extents[2]))
        return float(np.linalg.norm(self.half_extents))


class FixtureSpec(Model):
    """An articulated body standing fixed in the scene (a cabinet with a drawer): its URDF, where it stands, and
    the one joint a task works. Its reading, under the fixture's name, is the pose of that joint's child link
    (the cabinet's: the handle's centre) and the joint's value."""

    urdf: str  # relative to the tasks/ folder of the spec folder (or the built-in one): boxes only
    position: Position  # the URDF's base origin, task frame
    yaw: Literal[0, 90, 180, 270] = 0  # degrees about z from the task frame: its boxes stay axis-aligned
    joint: str  # the one moving joint (prismatic), closed (at its lower limit) at every reset
    # links the gripper's fingers may touch (the handle); the safety check keeps every other robot shape from
    # them, and every robot shape from the fixture's other links
    touchable: list[str] = []
    # how far the fingers of a gripper commanded shut may be commanded into a touchable link, m: a grip closing on
    # the handle commands them past its surface (half the bar's width each, fully closed); an open hand may only
    # touch it (envfactory/geometry/fixture_hold.py)
    touch_depth: Annotated[Positive, Field(le=0.05)] = 0.01
    friction: Annotated[NonNegative, Field(le=100.0)] = 1.0  # N: the joint's dry friction
    damping: Annotated[NonNegative, Field(le=100.0)] = 2.0  # N s/m: the joint's viscous damping


class GripperUse(Model):
    in_action: bool = False
    at_reset: Literal["open", "closed", "unchanged"] | Real = "unchanged"  # or a joint value


class LiftSpec(Model):
    """The lift stage as a task declares it (the multi_goal kwarg): lift the object above its spawn point, then
    go for the goal."""

    enabled: bool = True  # multi_goal
    height: Annotated[Positive, Field(le=2.0)] = 0.15  # lift_height, m


class GoalPartSpec(Model):
    """Another object's goal, held at a fixed offset from the goal (task frame): a stacked cube's, on top of
    the cube the goal places."""

    offset: Position


TURN_AXES = {"x": (1.0, 0.0, 0.0), "-x": (-1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "-y": (0.0, -1.0, 0.0)}
TURN_AXES.update({"z": (0.0, 0.0, 1.0), "-z": (0.0, 0.0, -1.0)})


class OrientationGoalSpec(Model):
    """An object's orientation as part of the goal: as it spawns (upright), turned by `angle` about one of `axes`
    of the task frame, drawn at each reset."""

    tolerance: Annotated[Positive, Field(le=3.1416)]  # rad: the angle between the object's orientation and the goal's
    angle: Annotated[Positive, Field(le=180.0)] = 90.0  # degrees: a quarter turn puts a side face down
    axes: list[Literal["x", "-x", "y", "-y", "z", "-z"]] = Field(default=["x", "-x", "y", "-y"], min_length=1)


class GoalSpec(Model):
    achieved: str  # "ee.position" or "<object>.position"
    tolerance: Positive
    box: tuple[Position, Position]
    random: bool = True  # random_goal; otherwise the static goal below
    static: Position | None = None  # the goal when random is false; the box centre if unset
    sampling_tries: int = Field(default=20, ge=1, le=1000)
    # a random goal within tolerance of where the achieved point starts is a success nobody earned: drawn again
    # unless this says such goals are wanted
    allow_achieved_at_reset: bool = False
    lift: LiftSpec | None = None
    # false: the object travels to the goal on its own (struck or thrown), so the goal box may lie beyond the
    # arm's reach and `validate` does not ask the arm to reach it
    within_reach: bool = True
    # more objects with goals, each at the goal plus its offset: the desired and achieved goals hold every
    # part in turn (the achieved object's first), and success needs each within tolerance
    also: dict[str, GoalPartSpec] = {}
    # objects' orientations as part of the goal, after the positions in the goal vectors: a quaternion (x, y, z, w)
    # in the task frame each, w >= 0; success needs each within its own angle tolerance too
    orientation: dict[str, OrientationGoalSpec] = {}

    @field_validator("box")
    @classmethod
    def _ordered_box(cls, box):
        # a flat box (low == high on an axis) is a goal at a fixed height or line
        low, high = box
        if any(lo > hi for lo, hi in zip(low, high)):
            raise ValueError(f"box low {list(low)} exceeds high {list(high)}")
        return box

    @model_validator(mode="after")
    def _static_in_box(self) -> "GoalSpec":
        low, high = self.box
        if self.static is not None and not all(lo <= v <= hi for v, lo, hi in zip(self.static, low, high)):
            raise located("static", f"static goal {list(self.static)} lies outside the goal box")
        source = self.achieved.partition(".")[0]
        if not self.within_reach and source == "ee":
            raise located("within_reach", "the EE is the arm's own: its goal must be within reach")
        if self.also and source == "ee":
            raise located("also", "goals of several parts are objects' goals: the achieved goal must be an object's")
        if source in self.also:
            raise located(f"also.{source}", f"{source!r} is the achieved goal already: an object has one goal")
        if self.also and self.lift is not None:
            raise located("lift", "the lift stage raises one object: it cannot go with goals for several ('also')")
        if self.orientation and self.lift is not None:
            raise located("lift", "the lift stage's goal is a point: it cannot go with an orientation goal")
        if "ee" in self.orientation:
            raise located("orientation.ee", "orientation goals are objects': the EE's is the arm's own")
        return self

    @property
    def parts(self) -> tuple[str, ...]:
        """What the goal places, in the goal vectors' order: the achieved point, then each 'also' object."""
        return (self.achieved.partition(".")[0], *self.also)

    @property
    def part_offsets(self) -> np.ndarray:
        """Each part's goal from the goal, (parts, 3), task frame."""
        return np.array([np.zeros(3), *(np.asarray(part.offset, float) for part in self.also.values())])

    @property
    def static_goal(self) -> tuple[float, float, float]:
        if self.static is not None:
            return self.static
        low, high = self.box
        return tuple((lo + hi) / 2 for lo, hi in zip(low, high))


class RewardSets(Model):
    sparse: dict[str, TermRef]
    dense: dict[str, TermRef]


class TerminationRef(Model):
    """A termination term by name, its params, and the reward type it applies on."""

    term: str
    params: dict[str, Any] = {}
    when: Literal["always", "sparse", "dense"] = "always"


class ExpertRef(Model):
    """The scripted policy that solves the task, and its robot-specific params."""

    policy: str
    params: dict[str, Any] = {}

    @model_validator(mode="before")
    @classmethod
    def _bare_name(cls, value):
        return {"policy": value} if isinstance(value, str) else value


class TaskSpec(Model):
    name: str
    label: str
    gripper: GripperUse = GripperUse()
    objects: dict[str, ObjectSpec] = {}
    # articulated bodies fixed in the scene; a goal, a term or an expert names one as it names an object
    fixtures: dict[str, FixtureSpec] = {}
    goal: GoalSpec
    observation: list[dict[str, dict[str, Any]]] = Field(min_length=1)
    reward: RewardSets
    termination: dict[str, TerminationRef] = {}
    expert: ExpertRef | None = None
    # sim-to-real: sampled physics, sensing and timing (off unless randomization.enabled, the randomize kwarg)
    randomization: RandomizationSpec = RandomizationSpec()
    kwargs: dict[str, str] = {}

    @model_validator(mode="after")
    def _fixture_names(self) -> "TaskSpec":
        for name in self.fixtures:
            if name in self.objects or name == "ee":
                raise located(
                    f"fixtures.{name}", f"{name!r} names an object already: a fixture needs a name of its own"
                )
        return self

    @field_validator("observation", mode="before")
    @classmethod
    def _normalise_observation(cls, entries):
        # YAML lets a term be a bare name or a one-key mapping to its params.
        if not isinstance(entries, (list, tuple)):
            raise ValueError("must be a list of term names or one-key mappings of name to params")
        normalised = []
        for index, entry in enumerate(entries):
            if isinstance(entry, str):
                normalised.append({entry: {}})
            elif (
                isinstance(entry, dict)
                and len(entry) == 1
                and isinstance(next(iter(entry.values())), (dict, type(None)))
            ):
                ((name, params),) = entry.items()
                normalised.append({name: dict(params or {})})
            else:
                raise ValueError(f"entry {index} must be a term name or a one-key mapping of name to params")
        return normalised
