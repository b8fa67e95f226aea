"""The rows of a collision pair list checked before they are used: their form as the generator writes them (a
hand-edited row of another form is named by its line, where a short one would fail deep inside as an
IndexError), and the structure a skip claims, against the robot's own model (a skip marked `adjacent` for two
links that are not would switch a real self-collision pair off, once its checksum was recomputed)."""

from __future__ import annotations

import yaml

from envfactory.schema.numbers import is_number
from envfactory.schema.sources import Loader

# What a row of each section holds, as the generator writes it.
ROW_FORMS = {
    "skipped": ("[shape, shape, reason]", lambda row: isinstance(row[2], str)),
    "pair_margins": ("[shape, shape, margin in m]", lambda row: is_number(row[2])),
    "never_near": ("[shape, shape]", lambda row: True),
}


def _well_formed(row, form) -> bool:
    shape, holds = form
    size = shape.count(",") + 1
    return isinstance(row, list) and len(row) == size and all(isinstance(n, str) for n in row[:2]) and holds(row)


def malformed_rows(text: str, data: dict) -> list[tuple[int, str]]:
    """(line, message) of every section that is not a list and every row not of its section's form, in file
    order, located from the YAML nodes. `data` is the text loaded: a list in good form is recognized from it,
    and only a list with a fault is parsed again for its lines (a tenth of a second for a long list)."""
    if all(
        isinstance(data.get(key), list) and all(_well_formed(row, form) for row in data[key])
        for key, form in ROW_FORMS.items()
        if key in data
    ):
        return []
    found = []
    for key, value in yaml.compose(text, Loader=Loader).value:
        form = ROW_FORMS.get(key.value)
        if form is None:
            continue
        shape = form[0]
        if not isinstance(value, yaml.SequenceNode):
            found.append((key.start_mark.line + 1, f"{key.value} is not a list of rows {shape}"))
            continue
        for node in value.value:
            row = yaml.safe_load(yaml.serialize(node))
            if not _well_formed(row, form):
                found.append((node.start_mark.line + 1, f"{key.value} row {row!r} is not {shape}"))
    return sorted(found)


def misreported_structure(skipped: dict[frozenset, str], collision, reasons) -> list[str]:
    """The skips whose structural reason (one of `reasons`) is not the one the robot's collision model exempts
    that pair for, from its URDF (rigidly joined, adjacent, the gripper's own mechanism)."""
    names = [shape.name for shape in collision.shapes]
    structural = {frozenset((names[a], names[b])): why for a, b, why in collision.self_pairs if why}
    return sorted(
        f"{' and '.join(sorted(key))} as {why!r}, which the robot's model finds "
        + (f"{structural[key]!r}" if key in structural else "to be neither (a pair to measure)")
        for key, why in skipped.items()
        if why in reasons and structural.get(key) != why
    )
