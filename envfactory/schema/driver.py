"""How a robot's driver is brought to the env's step: the service calls that set its timing at every
connection, and when a commanded motion counts as done on the real arm.

A step means one thing on every backend: it ends with the commanded motion done (or the arm stopped with
the reason), and the observation is read after that. A simulator plays the motion inside the cycle; a real
driver is given the motion's duration (a trajectory's time_from_start, or a time profile set once through its
own service, as xs_sdk's operating modes), and the step waits until the arm is at its target.
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import Field, model_validator

from envfactory.schema.base import Model, located
from envfactory.schema.errors import suggest
from envfactory.schema.messages import placeholder_paths
from envfactory.schema.numbers import Real

# What a setup call's request may hold: the motion's duration the env plays every arm command over
# (its action_speed), and the profile's ramp at either end of it, both in whole milliseconds.
SETUP_PLACEHOLDERS = {"$motion_ms", "$ramp_ms"}
# The ramp as a share of the motion: xs_sdk's stock mode config accelerates over 300 of its 2000 ms.
RAMP_SHARE = 0.15


class DriverCall(Model):
    """A service call made at every connection before any motion (xs_sdk's operating modes, say). A driver
    that refuses it stops the env at connect, naming the call: the arm never runs on a timing it was not
    given."""

    service: str
    type: str  # the service type, e.g. interbotix_xs_msgs/OperatingModes
    request: dict[str, Any]

    @model_validator(mode="after")
    def _placeholders_known(self) -> "DriverCall":
        for name, path in placeholder_paths(self.request).items():
            if name not in SETUP_PLACEHOLDERS:
                raise located(
                    f"request.{path}",
                    f"unknown placeholder {name!r}"
                    f"{suggest(name, SETUP_PLACEHOLDERS)} (valid: "
                    f"{', '.join(sorted(SETUP_PLACEHOLDERS))})",
                )
        return self

    @property
    def sets_motion_time(self) -> bool:
        """Whether the call gives the driver the motion's duration (its arm commands then take that long)."""
        return "$motion_ms" in placeholder_paths(self.request)


def setup_values(motion_s: float) -> dict[str, int]:
    """What a setup request's placeholders stand for: the motion's duration and its ramp, in milliseconds."""
    return {"$motion_ms": round(1000 * motion_s), "$ramp_ms": round(1000 * motion_s * RAMP_SHARE)}


class ServiceType(Model):
    """A driver's own service type, field by field, as its ROS installation defines it (the twin's server
    checks calls against it, as a rosbridge server does)."""

    request: dict[str, str] = {}
    response: dict[str, str] = {}


class Settle(Model):
    """When a real step's motion is done: every arm joint within `tolerance` of its target and slower than
    `velocity`, so the observation after it sees an arm at rest, as a simulated step's does. An arm at rest short
    of its target once the driver's time is over, by at most `held_back` (held back by what it pushes, as a
    simulated arm is), has done its motion too, and the step records the gap; so has one held back and still
    creeping or trembling at the end of `margin_s` (pressing into what holds it), slowed to a quarter of its
    fastest. Any other motion not done `margin_s` after the driver's time stops the arm and ends the episode
    with the reason."""

    tolerance: Annotated[Real, Field(gt=0, le=0.2)] = 0.01  # rad
    velocity: Annotated[Real, Field(gt=0, le=1.0)] = 0.05  # rad/s (a driver that publishes no velocity reads 0)
    held_back: Annotated[Real, Field(gt=0, le=0.2)] = 0.05  # rad
    margin_s: Annotated[Real, Field(gt=0, le=10.0)] = 1.0

    @model_validator(mode="after")
    def _held_back_beyond_tolerance(self) -> "Settle":
        if self.held_back < self.tolerance:
            raise located(
                "held_back",
                f"held_back {self.held_back} is below the tolerance {self.tolerance}: an "
                "arm within the tolerance is at its target",
            )
        return self
