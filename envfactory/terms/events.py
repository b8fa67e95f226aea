"""Event terms: physical quantities sampled at every reset (and, with `every`, again during the episode) and
set through the backend, for training that survives the difference between engines, or between the
simulation and the real arm. Each term samples one value from its range and names what it sets."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydantic import model_validator

from envfactory.schema.numbers import Real
from envfactory.step_state import PhysicsChange
from envfactory.terms.library import TermContext, TermParams, UnknownReference, event_term


class Sampled(TermParams):
    """Where the value comes from: `range` (absolute, in the term's unit) or `scale` (times the value the spec
    declares), drawn uniformly or log-uniformly (every ratio equally likely: masses, gains)."""

    range: tuple[Real, Real] | None = None
    scale: tuple[Real, Real] | None = None
    distribution: Literal["uniform", "log_uniform"] = "uniform"

    @model_validator(mode="after")
    def _one_source(self) -> "Sampled":
        if (self.range is None) == (self.scale is None):
            raise ValueError("give exactly one of 'range' (absolute) and 'scale' (times the spec's value)")
        low, high = self.range if self.range is not None else self.scale
        if low > high:
            raise ValueError(f"low {low} exceeds high {high}")
        if self.scale is not None and low <= 0:
            raise ValueError(f"scale {list(self.scale)}: a factor must be positive")
        return self


class ObjectSampled(Sampled):
    object: str = "cube"


@dataclass(frozen=True)
class SampledQuantity:
    """What a bound event samples: the quantity it sets, of which thing, and the absolute interval."""

    quantity: str
    target: str
    low: float
    high: float
    distribution: str

    def sample(self, rng: np.random.Generator) -> PhysicsChange:
        if self.low == self.high:
            value = self.low
        elif self.distribution == "log_uniform":
            value = math.exp(rng.uniform(math.log(self.low), math.log(self.high)))
        else:
            value = rng.uniform(self.low, self.high)
        return PhysicsChange(self.quantity, self.target, float(value))


def _resolve(
    params: Sampled, quantity: str, target: str, declared: float | None, unit: str, plausible: tuple[float, float]
) -> SampledQuantity:
    """The absolute interval, checked against what such a quantity can plausibly be (ValueError says why not)."""
    if params.scale is not None:
        if declared is None:
            raise ValueError(f"{quantity} has no value in the spec to scale: give an absolute 'range' in {unit}")
        low, high = (factor * declared for factor in params.scale)
    else:
        low, high = params.range
    least, most = plausible
    if low < least or high > most:
        raise ValueError(
            f"{quantity} from {low:g} to {high:g} {unit} leaves the plausible [{least:g}, {most:g}] {unit}"
        )
    if params.distribution == "log_uniform" and low <= 0:
        raise ValueError(f"a log-uniform {quantity} needs a positive low end, not {low:g} {unit}")
    return SampledQuantity(quantity, target, float(low), float(high), params.distribution)


def _object(layout: TermContext, params: ObjectSampled):
    objects = layout.task.objects
    if params.object not in objects:
        raise UnknownReference(f"object {params.object!r} is not one of the task's objects ({list(objects) or 'none'})")
    return objects[params.object]


def _bind_object_mass(layout: TermContext, params: ObjectSampled) -> SampledQuantity:
    mass = _object(layout, params).mass
    return _resolve(params, "object_mass", params.object, mass, "kg", (1e-3, 100.0))


def _bind_object_friction(layout: TermContext, params: ObjectSampled) -> SampledQuantity:
    friction = _object(layout, params).friction
    return _resolve(params, "object_friction", params.object, friction, "", (0.0, 10.0))


def _bind_table_friction(layout: TermContext, params: Sampled) -> SampledQuantity:
    return _resolve(params, "table_friction", "", None, "", (0.0, 10.0))


def _bind_arm_damping(layout: TermContext, params: Sampled) -> SampledQuantity:
    """Checked against each arm joint: a damping whose torque at the joint's rated speed exceeds its rated effort
    leaves a motor that could never reach that speed. Past it PyBullet's joints blow up (measured with the
    shipped Push experts, full physics: an arm whose lightest wrist allows 0.32 reads 31 rad/s at 2 and stays
    calm at 1; one that allows 6.4 is calm at 20 and reads 100 rad/s at 100)."""
    bound = _resolve(params, "arm_damping", "", None, "N m s/rad", (0.0, 100.0))
    robot = layout.robot
    for joint, effort, speed in zip(robot.arm_joints, robot.arm_efforts, robot.arm_velocities):
        if bound.high * speed > effort:
            raise ValueError(
                f"arm_damping up to {bound.high:g} N m s/rad would take {bound.high * speed:.3g} N m from joint "
                f"{joint.name} at its rated speed of {speed:g} rad/s, over its rated effort of {effort:g} N m (the "
                f"robot's URDF limits): its motor could never drive it; for robot {robot.name}, at most "
                f"{min(e / v for e, v in zip(robot.arm_efforts, robot.arm_velocities)):.3g} N m s/rad"
            )
    return bound


def _bind_gripper_force(layout: TermContext, params: Sampled) -> SampledQuantity:
    gripper = layout.robot.gripper
    if gripper is None:
        raise UnknownReference(f"robot {layout.robot.name!r} has no gripper")
    return _resolve(params, "gripper_force", "", gripper.force, "N", (1e-3, 10 * gripper.force))


def _register(name: str, params: type[Sampled], bind, unit: str, doc: str) -> None:
    """One event term: every shipped one draws its bound quantity; they differ in what they bind and say."""

    def draw(rng: np.random.Generator, bound: SampledQuantity) -> PhysicsChange:
        return bound.sample(rng)

    draw.__name__, draw.__qualname__, draw.__doc__ = name, name, doc
    event_term(name=name, params=params, bind=bind, unit=unit)(draw)


_register("object_mass", ObjectSampled, _bind_object_mass, "kg", "The object's mass (its inertia scales with it).")
_register(
    "object_friction",
    ObjectSampled,
    _bind_object_friction,
    "",
    "The object's lateral friction coefficient (a contact rubs with the product of both surfaces').",
)
_register(
    "table_friction",
    Sampled,
    _bind_table_friction,
    "",
    "The table's lateral friction coefficient (a range only: the specs give the table none to scale).",
)
_register("arm_damping", Sampled, _bind_arm_damping, "N m s/rad", "Viscous damping of every arm joint (a range only).")
_register("gripper_force", Sampled, _bind_gripper_force, "N", "The gripper drive's force limit.")
