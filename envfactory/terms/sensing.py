"""Sensing and timing terms: what the policy sees and when its action lands, as on a real arm. Each term makes a
sensor per env: it sees the observation vector on its way out and the action on its way in. They act on the
'observation' vector only: a goal env's achieved and desired goals stay exact, so rewards recomputed from them
(HER) equal the step's."""

from __future__ import annotations

from collections import deque
from typing import Annotated

import numpy as np
from pydantic import Field

from envfactory.schema.numbers import NonNegative
from envfactory.terms.library import OBSERVATIONS, TermContext, TermParams, UnknownReference, sensing_term

MAX_DELAY_STEPS = 10  # beyond this a policy acting on the observation would be playing a different game


class Sensor:
    """Stateful, one per env and term; the identity unless a term overrides a part."""

    def reset(self, rng: np.random.Generator, observation: np.ndarray, hold_action: np.ndarray) -> None:
        self.rng = rng

    def observe(self, observation: np.ndarray) -> np.ndarray:
        return observation

    def act(self, action: np.ndarray) -> np.ndarray:
        return action


class Columns(TermParams):
    # observation terms (names from task.observation) it applies to; empty: the whole vector
    observations: list[str] = []


def _columns(layout: TermContext, params: Columns) -> np.ndarray:
    """The observation vector's columns of the named terms (ValueError names an unknown one)."""
    slots = layout.observation_slots
    if not params.observations:
        return np.arange(sum(slot.size for slot in slots))
    known = [slot.name for slot in slots]
    unknown = [name for name in params.observations if name not in known]
    goal_dependent = [name for name in unknown if name in OBSERVATIONS and OBSERVATIONS[name].goal_dependent]
    if goal_dependent:
        raise UnknownReference(
            f"observations {goal_dependent} depend on the goal: a goal env leaves them out of its "
            f"'observation' (the goal is in desired_goal), so no sensor can read them there"
        )
    if unknown:
        raise UnknownReference(f"observations {unknown} are not in this task's observation (it has {known})")
    return np.concatenate([np.arange(slot.start, slot.stop) for slot in slots if slot.name in params.observations])


class Noise(Columns):
    std: Annotated[NonNegative, Field(le=1.0)]  # white noise, fresh each step, in each column's unit
    bias_std: Annotated[NonNegative, Field(le=1.0)] = 0.0  # an offset drawn at reset, held for the episode
    drift_std: Annotated[NonNegative, Field(le=1.0)] = 0.0  # the offset's random walk, per step


class NoiseSensor(Sensor):
    def __init__(self, columns: np.ndarray, params: Noise):
        self.columns, self.params = columns, params

    def reset(self, rng, observation, hold_action):
        super().reset(rng, observation, hold_action)
        self.bias = (
            rng.normal(0.0, self.params.bias_std, self.columns.size)
            if self.params.bias_std
            else np.zeros(self.columns.size)
        )

    def observe(self, observation):
        params, out = self.params, observation.copy()
        if params.drift_std:
            self.bias = self.bias + self.rng.normal(0.0, params.drift_std, self.columns.size)
        out[self.columns] += self.bias + (self.rng.normal(0.0, params.std, self.columns.size) if params.std else 0.0)
        return out


def _bind_columns(layout: TermContext, params: Columns) -> tuple[np.ndarray, Columns]:
    return _columns(layout, params), params


# Noise is judged against the range its observation term declares: a sensor whose error spreads over more than
# this share of the term's typical column range (13 mm of a 1.3 m position box, 0.06 rad of a 2π joint range) no
# longer reports the state, and whatever a policy learns under it is not the task. The shipped cube tracker's
# spread is 0.0028 m, about a tenth of the UR5e's 0.024 m limit.
NOISE_RANGE_SHARE = 0.01


def _bind_noise(layout: TermContext, params: Noise) -> tuple[np.ndarray, Noise]:
    """The columns, once the noise's spread over an episode (white, bias and drift together) is found plausible
    for each observation term it touches (ValueError names the term, the spread and the range it was judged by)."""
    columns = _columns(layout, params)
    steps = layout.episode_steps
    spread = float(np.sqrt(params.std**2 + params.bias_std**2 + params.drift_std**2 * steps))
    for slot in layout.observation_slots:
        if params.observations and slot.name not in params.observations:
            continue
        widths = np.asarray(slot.high, float) - np.asarray(slot.low, float)
        widths = widths[np.isfinite(widths) & (widths > 0)]
        if not widths.size:
            continue
        typical = float(np.median(widths))
        if spread > NOISE_RANGE_SHARE * typical:
            raise ValueError(
                f"noise spreading {spread:.3g} (std {params.std:g}, bias_std {params.bias_std:g}, drift_std "
                f"{params.drift_std:g} over {steps} steps) on {slot.name!r} ({slot.description.unit}) is over "
                f"{NOISE_RANGE_SHARE:.0%} of its columns' typical range ({typical:.3g}): at most "
                f"{NOISE_RANGE_SHARE * typical:.3g}; a sensor that noisy hides the state it reports"
            )
    return columns, params


@sensing_term(params=Noise, bind=_bind_noise, unit="the columns' own")
def observation_noise(bound: tuple[np.ndarray, Noise]) -> NoiseSensor:
    """Gaussian noise on the named observation terms' columns: white per step, plus a per-episode bias that may
    drift as a random walk."""
    return NoiseSensor(*bound)


class Delay(TermParams):
    steps: int = Field(ge=0, le=MAX_DELAY_STEPS)  # 0: measured, and under half a step


class Lag:
    """Hands back what it was given `steps` calls before; `first` until then."""

    def __init__(self, steps: int, first: np.ndarray):
        self.queue = deque([first.copy()] * steps, maxlen=steps + 1)

    def pass_on(self, item: np.ndarray) -> np.ndarray:
        self.queue.append(np.array(item, copy=True))
        return self.queue.popleft()


class ObservationDelaySensor(Sensor):
    def __init__(self, steps: int):
        self.steps = steps

    def reset(self, rng, observation, hold_action):
        super().reset(rng, observation, hold_action)
        self.lag = Lag(self.steps, observation)

    def observe(self, observation):
        return self.lag.pass_on(observation)


@sensing_term(params=Delay, unit="steps")
def observation_delay(params: Delay) -> ObservationDelaySensor:
    """The observation arrives `steps` steps late (the reset's observation fills the first ones)."""
    return ObservationDelaySensor(params.steps)


class ActionDelaySensor(Sensor):
    def __init__(self, steps: int):
        self.steps = steps

    def reset(self, rng, observation, hold_action):
        super().reset(rng, observation, hold_action)
        self.lag = Lag(self.steps, hold_action)

    def act(self, action):
        return self.lag.pass_on(action)


@sensing_term(params=Delay, unit="steps")
def action_delay(params: Delay) -> ActionDelaySensor:
    """Each action is applied `steps` steps after the policy gives it (the first steps of an episode hold the
    arm where it is); the safety check judges it when it is applied."""
    return ActionDelaySensor(params.steps)


class Repeats(Columns):
    probability: float = Field(ge=0.0, lt=1.0)


class RepeatSensor(Sensor):
    def __init__(self, columns: np.ndarray, probability: float):
        self.columns, self.probability = columns, probability

    def reset(self, rng, observation, hold_action):
        super().reset(rng, observation, hold_action)
        self.last = observation[self.columns].copy()

    def observe(self, observation):
        if self.rng.random() < self.probability:
            observation = observation.copy()
            observation[self.columns] = self.last
        self.last = observation[self.columns].copy()
        return observation


@sensing_term(params=Repeats, bind=_bind_columns, unit="")
def repeated_readings(bound: tuple[np.ndarray, Repeats]) -> RepeatSensor:
    """With this probability a step's reading of the named observation terms is dropped and the last one seen
    repeats (a joint-state message that did not arrive in time)."""
    columns, params = bound
    return RepeatSensor(columns, params.probability)
