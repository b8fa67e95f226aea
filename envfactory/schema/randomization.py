"""Sim-to-real by spec: what the physics samples (events) and how sensing and timing differ from the truth
(sensing), declared as terms under `task.randomization`. Off unless `enabled` (the `randomize` kwarg), so the
original suite's IDs keep its contract."""

from __future__ import annotations

from typing import Any

from pydantic import Field, model_validator

from envfactory.schema.base import Model
from envfactory.schema.numbers import Positive

# An interval event at most this often apart, in steps or simulated seconds: beyond an episode's worth
# (the longest registered episode is 10,000 steps of 0.5 s) it would never fire.
MAX_INTERVAL_STEPS = 10_000
MAX_INTERVAL_SECONDS = 5_000.0


class Every(Model):
    """An interval: every so many steps, or every so many seconds of simulated time (exactly one of them)."""

    steps: int | None = Field(default=None, ge=1, le=MAX_INTERVAL_STEPS)
    seconds: Positive | None = Field(default=None, le=MAX_INTERVAL_SECONDS)

    @model_validator(mode="after")
    def _one(self) -> "Every":
        if (self.steps is None) == (self.seconds is None):
            raise ValueError("give exactly one of 'steps' and 'seconds'")
        return self


class EventRef(Model):
    """An event term by name: when it samples (at every reset; `every` also samples it again at that interval
    during the episode), and its params (what it varies and over which range)."""

    term: str
    every: Every | None = None
    params: dict[str, Any] = {}


class SensingRef(Model):
    """A sensing or timing term by name, and its params."""

    term: str
    params: dict[str, Any] = {}


class RandomizationSpec(Model):
    enabled: bool = False  # the randomize kwarg
    events: dict[str, EventRef] = {}
    sensing: dict[str, SensingRef] = {}
