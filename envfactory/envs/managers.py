"""Observation and reward managers: run the compiled terms, print their tables."""

from __future__ import annotations

from typing import Iterable, Sequence

import numpy as np
from gymnasium import spaces

from envfactory.compiler import ImageSlot, ObservationSlot, TerminationSlot, WeightedTerm
from envfactory.step_state import EnvState


class ObservationManager:
    def __init__(self, slots: Sequence[ObservationSlot]):
        self.slots = tuple(slots)
        self.size = sum(slot.size for slot in self.slots)
        self.low = np.concatenate([slot.low for slot in self.slots]).astype(np.float32)
        self.high = np.concatenate([slot.high for slot in self.slots]).astype(np.float32)
        self._calls = [(slot.term.fn, slot.bound, slice(slot.start, slot.stop)) for slot in self.slots]

    def compute(self, state: EnvState) -> tuple[np.ndarray, list[str]]:
        """The observation vector, held to its declared bounds, and the columns that had to be clipped
        (a reading the derived bounds did not foresee: the env flags it in info and logs it)."""
        buffer = np.empty(self.size, dtype=np.float32)
        for fn, params, where in self._calls:
            buffer[where] = fn(state, params)
        if not ((buffer < self.low).any() or (buffer > self.high).any()):
            return buffer, []
        outside = ((buffer < self.low) | (buffer > self.high)).nonzero()[0]
        names = [f"{self.column_name(int(i))}={float(buffer[i]):.4g}" for i in outside]
        return np.clip(buffer, self.low, self.high), names

    def column_name(self, index: int) -> str:
        for slot in self.slots:
            if slot.start <= index < slot.stop:
                return f"{index} ({slot.name}[{index - slot.start}])"
        raise IndexError(index)

    def table(self) -> list[tuple[str, str, str, str, str]]:
        rows = []
        for slot in self.slots:
            index = str(slot.start) if slot.size == 1 else f"{slot.start}–{slot.stop - 1}"
            d = slot.description
            rows.append((index, str(slot.size), d.component, d.source, d.unit))
        return rows


class ImageManager:
    """The camera terms: one Dict observation key each, captured once per observation."""

    def __init__(self, slots: Sequence[ImageSlot], camera):
        self.slots = tuple(slots)
        self.camera = camera

    def __bool__(self) -> bool:
        return bool(self.slots)

    def spaces(self) -> dict[str, spaces.Box]:
        return {
            slot.name: spaces.Box(slot.low, slot.high, shape=slot.shape, dtype=slot.term.dtype) for slot in self.slots
        }

    def capture(self, backend) -> dict[str, np.ndarray]:
        if not self.slots:
            return {}
        frame = backend.capture(self.camera)
        return {slot.name: slot.term.fn(frame) for slot in self.slots}


def info_columns(
    info: dict | Sequence[dict] | np.ndarray, keys: Iterable[str], batch: tuple[int, ...]
) -> dict[str, np.ndarray]:
    """Step-time records as arrays: from one info dict (shared by the batch, left to
    broadcast), or from one dict per goal (HER), shaped batch + the record's own shape."""
    if isinstance(info, dict):
        # one record for the whole batch: numpy broadcasting spreads it, no copies needed
        return {key: np.asarray(_entry(info, key), dtype=float) for key in keys}
    infos = np.asarray(info, dtype=object).reshape(-1)
    count = int(np.prod(batch)) if batch else 1
    if infos.size != count:
        raise ValueError(f"got {infos.size} info dicts for a batch of {count} goals")
    columns = {}
    for key in keys:
        stacked = np.array([np.asarray(_entry(item, key), dtype=float) for item in infos])
        columns[key] = stacked.reshape(batch + stacked.shape[1:])
    return columns


def _entry(info: dict, key: str):
    try:
        return info[key]
    except KeyError:
        raise KeyError(
            f"step info lacks {key!r}, which a reward or termination term reads: pass the info dict the "
            f"step returned (info keys present: {sorted(info)})"
        ) from None


class RewardManager:
    """The reward: the weighted sum of the active reward set's terms, pure in (achieved, desired, info) and
    vectorised over a batch, so that HER's relabelled rewards are exact; and the state-dependent values those
    terms read from info, measured at step time."""

    def __init__(self, terms: Sequence[WeightedTerm], tolerance: float, info_keys: Sequence[str]):
        self.terms = tuple(terms)
        self.tolerance = tolerance
        self.info_keys = tuple(info_keys)
        self._measured = [(t.term.info_keys[0], t.term.measure, t.bound) for t in self.terms if t.term.measure]

    def reward(self, achieved: np.ndarray, desired: np.ndarray, info) -> np.ndarray:
        achieved, desired = np.asarray(achieved, float), np.asarray(desired, float)
        batch = achieved.shape[:-1]
        columns = info_columns(info, self.info_keys, batch)
        if not batch:  # one step's reward: summed as plain numbers, numpy's 0-d arithmetic costs more
            return np.asarray(
                sum(
                    (
                        term.weight * float(term.term.fn(achieved, desired, columns, term.bound, self.tolerance))
                        for term in self.terms
                    ),
                    0.0,
                )
            )
        total = np.zeros(batch)
        for term in self.terms:
            total = total + term.weight * term.term.fn(achieved, desired, columns, term.bound, self.tolerance)
        return total

    def measure(self, state: EnvState) -> dict[str, float]:
        """Values of the state-dependent terms, for the step to record in info."""
        return {key: float(fn(state, bound)) for key, fn, bound in self._measured}

    def table(self) -> list[tuple[str, str, str, str, str]]:
        """(name, term, params, weight, meaning) of each active term."""
        rows = []
        for t in self.terms:
            params = ", ".join(
                f"{key}={value}" for key, value in t.params.model_dump(by_alias=True).items() if value is not None
            )
            rows.append((t.name, t.term.name, params, f"{t.weight:g}", t.term.description))
        return rows


class TerminationManager:
    """Whether an episode ends: any active termination term (the reward type's, and those `when: always`), pure
    in (achieved, desired, info) and vectorised over a batch as the reward is."""

    def __init__(self, terminations: Sequence[TerminationSlot], tolerance: float, info_keys: Sequence[str]):
        self.terminations = tuple(t for t in terminations if t.active)
        self.tolerance = tolerance
        self.info_keys = tuple(info_keys)

    def terminated(self, achieved: np.ndarray, desired: np.ndarray, info) -> np.ndarray:
        achieved, desired = np.asarray(achieved, float), np.asarray(desired, float)
        batch = achieved.shape[:-1]
        done = np.zeros(batch, dtype=bool)
        if not self.terminations:
            return done
        columns = info_columns(info, self.info_keys, batch)
        for term in self.terminations:
            done |= term.term.fn(achieved, desired, columns, term.bound, self.tolerance)
        return done
