"""What every spec model shares: unknown keys are errors, values are frozen."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict

from envfactory.schema.numbers import Angle, Coordinate, Real

Vec3 = tuple[Real, Real, Real]
Position = tuple[Coordinate, Coordinate, Coordinate]  # metres, within the scene extent
Rpy = tuple[Angle, Angle, Angle]
Rgba = tuple[Real, Real, Real, Real]


class Model(BaseModel):
    # A typo is reported with its dotted path and the nearest valid name
    # instead of being silently ignored.
    # NaN and infinity are refused in every float (the Real type says so per field too).
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


def ordered(low, high, what: str = "") -> None:
    """Raise unless every component of `low` lies strictly below `high`."""
    pairs = zip(low, high) if isinstance(low, (tuple, list)) else [(low, high)]
    if any(lo >= hi for lo, hi in pairs):
        label = f"{what} " if what else ""
        raise ValueError(f"{label}min {_show(low)} must lie below max {_show(high)} in every component")


def _show(value):
    return list(value) if isinstance(value, (tuple, list)) else value


def in_unit_range(rgba) -> None:
    if any(not 0.0 <= c <= 1.0 for c in rgba):
        raise ValueError(f"rgba {list(rgba)}: every component lies in [0, 1]")


def located(path: str, message: str) -> ValueError:
    """A model validator's error pinned to a field below the model (`path` relative to it),
    so the report names that field's line rather than the model's."""
    return ValueError(f"@{path}@ {message}")


def split_located(message: str) -> tuple[str, str]:
    """(relative path, message) of a `located` error; ("", message) for any other."""
    if message.startswith("@") and "@ " in message[1:]:
        path, _, rest = message[1:].partition("@ ")
        return path, rest
    return "", message
