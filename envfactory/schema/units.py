"""Whether a number out of range looks like a unit mistake.

Specs take radians and metres. A value written in degrees, centimetres or millimetres lands out of range
by the factor between the units (57.3, 100, 1000); a range error then says which unit the value looks like
and what it is in the spec's unit, so the fix is read off the message.
"""

from __future__ import annotations

import math

DEGREES_PER_RADIAN = 180.0 / math.pi
# The last key of a dotted path (list indices skipped) says what a value measures.
ANGLE_KEYS = frozenset({"rpy", "mount_rpy", "top_down_rpy", "home", "lower", "upper", "delta", "max_joint_delta"})
LENGTH_KEYS = frozenset(
    {
        "mount",
        "xyz",
        "position",
        "box",
        "static",
        "size",
        "center",
        "top_z",
        "thickness",
        "offset",
        "eye",
        "target",
        "floor_z",
        "surface_margin",
        "table_footprint_margin",
        "tolerance",
        "min",
        "max",
        "ee_bounds",
        "padding",
        "grasp_height",
        "height",
        "clearance",
        "lift",
        "step",
        "paddle",
        "distance",
        "lateral_tolerance",
    }
)
# An angle is taken for degrees only beyond a full turn: no radian value of a spec goes there.
FULL_TURN = 2 * math.pi
# A length is taken for centimetres (millimetres) only when it is at least this many times its bound:
# a value a little out of range is a value a little wrong, not a unit.
CENTIMETRE_RATIO = 2.0
MILLIMETRE_RATIO = 20.0
SMALL_UNITS = (("centimetres", "cm", 100.0, CENTIMETRE_RATIO), ("millimetres", "mm", 1000.0, MILLIMETRE_RATIO))


def kind_of(path: str) -> str | None:
    """'angle', 'length' or None (unknown) for the value at a dotted spec path."""
    keys = [part for part in path.split(".") if part and not part.isdigit()]
    for key in reversed(keys[-2:]):  # a mapping of names (padding.<link>) is named by its parent
        if key in ANGLE_KEYS:
            return "angle"
        if key in LENGTH_KEYS:
            return "length"
    return None


def unit_hint(value: float, bound: float, kind: str | None) -> str:
    """'; looks like degrees: ...' when `value`, out of range past `bound` (the limit it broke), comes in range
    once read in the unit a mistake would give it; '' otherwise."""
    if kind is None or not math.isfinite(value) or not math.isfinite(bound):
        return ""
    limit = abs(bound)
    if kind == "angle":
        if abs(value) > FULL_TURN and abs(value / DEGREES_PER_RADIAN) <= max(limit, FULL_TURN):
            return f"; looks like degrees: angles are in radians ({value:g}° = {math.radians(value):.4g} rad)"
        return ""
    if limit == 0:
        return ""
    ratio = abs(value) / limit
    fits = [
        (name, symbol, factor)
        for name, symbol, factor, least in SMALL_UNITS
        if ratio >= least and abs(value) / factor <= limit
    ]
    if not fits:
        return ""
    readings = " or ".join(f"{value:g} {symbol} = {value / factor:g} m" for _, symbol, factor in fits)
    names = " or ".join(name for name, _, _ in fits)
    return f"; looks like {names}: lengths are in metres ({readings})"


def out_of_range_hint(path: str, value: float, low: float, high: float) -> str:
    """The unit hint of a value that lies outside [low, high], judged against the bound it broke."""
    if low <= value <= high:
        return ""
    return unit_hint(value, high if value > high else low, kind_of(path))
