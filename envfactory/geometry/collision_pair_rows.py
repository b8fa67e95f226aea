"""The rows of a collision pair list as the generator writes them: a hand-edited row of another form is named by
its line before any entry is read (a short row would otherwise fail deep inside as an IndexError)."""

from __future__ import annotations

import yaml

# What a row of each section holds, as the generator writes it.
ROW_FORMS = {
    "skipped": ("[shape, shape, reason]", lambda row: isinstance(row[2], str)),
    "pair_margins": ("[shape, shape, margin in m]", lambda row: _is_number(row[2])),
    "never_near": ("[shape, shape]", lambda row: True),
}


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def malformed_rows(text: str) -> list[tuple[int, str]]:
    """(line, message) of every section that is not a list and every row not of its section's form, in file
    order, located from the YAML nodes."""
    found = []
    for key, value in yaml.compose(text).value:
        form = ROW_FORMS.get(key.value)
        if form is None:
            continue
        shape, holds = form
        size = shape.count(",") + 1
        if not isinstance(value, yaml.SequenceNode):
            found.append((key.start_mark.line + 1, f"{key.value} is not a list of rows {shape}"))
            continue
        for node in value.value:
            row = yaml.safe_load(yaml.serialize(node))
            if not (isinstance(row, list) and len(row) == size and all(isinstance(n, str) for n in row[:2])) or not (
                holds(row)
            ):
                found.append((node.start_mark.line + 1, f"{key.value} row {row!r} is not {shape}"))
    return sorted(found)
