"""One env's randomization at run time: samples the compiled events and sets them through the backend, and runs
the sensing terms' sensors on the observation and the action.

Reproducible by construction: each reset draws one seed from the env's generator (after the spawn and the
goal, so a seeded reset places the same cube and goal with or without randomization), and the events and the
sensors get their own streams from it, so adding a sensor does not change what the physics samples.
"""

from __future__ import annotations

import numpy as np

from envfactory.compiler.blueprint import EventSlot

SEED_BOUND = 2**63


class Randomizer:
    def __init__(self, blueprint, backend, cycle_time: float):
        self.backend = backend
        self.events = blueprint.events
        self.sensors = [slot.term.fn(slot.bound) for slot in blueprint.sensing]
        self._every = [self._interval_steps(slot, cycle_time) for slot in self.events]
        self.values: dict[str, float] = {}  # the value each event set last: recorded in every step's info
        self._events_rng = self._sensing_rng = np.random.default_rng(0)
        self._steps = 0

    @staticmethod
    def _interval_steps(slot: EventSlot, cycle_time: float) -> int | None:
        """An interval in steps: simulated seconds pass a cycle a step."""
        if slot.every is None:
            return None
        if slot.every.steps is not None:
            return slot.every.steps
        return max(1, round(slot.every.seconds / cycle_time))

    def reset(self, rng: np.random.Generator) -> None:
        """A new episode: fresh streams from the env's generator, and every event sampled and set."""
        events, sensing = np.random.SeedSequence(int(rng.integers(SEED_BOUND))).spawn(2)
        self._events_rng, self._sensing_rng = np.random.default_rng(events), np.random.default_rng(sensing)
        self._steps = 0
        for slot in self.events:
            self._apply(slot)

    def start_sensing(self, observation: np.ndarray, hold_action: np.ndarray) -> None:
        """The episode's first true observation and the action that holds the arm: what delays start from."""
        for sensor in self.sensors:
            sensor.reset(self._sensing_rng, observation, hold_action)

    def act(self, action: np.ndarray) -> np.ndarray:
        for sensor in self.sensors:
            action = sensor.act(action)
        return action

    def observe(self, observation: np.ndarray) -> np.ndarray:
        for sensor in self.sensors:
            observation = sensor.observe(observation)
        return observation

    def before_step(self) -> None:
        """A step begins: the interval events due after the steps so far are sampled and set, so the values a
        step's info records are the ones that acted in it."""
        for slot, every in zip(self.events, self._every):
            if every is not None and self._steps > 0 and self._steps % every == 0:
                self._apply(slot)
        self._steps += 1

    def _apply(self, slot: EventSlot) -> None:
        change = slot.term.fn(self._events_rng, slot.bound)
        self.backend.apply_physics(change)
        self.values[slot.name] = change.value
