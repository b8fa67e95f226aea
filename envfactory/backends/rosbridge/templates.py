"""Filling a message template and reading a message through one.

Filling replaces each placeholder with its value and copies everything else,
in the template's key order (the order on the wire). Reading walks the
template over a message and collects the value at each placeholder; the
template's fixed values are not compared (a driver's header stamps and effort
readings are its own), except when a stop message is told from a command by
them.
"""

from __future__ import annotations

import copy
from typing import Any

from envfactory.schema.messages import is_placeholder


class TemplateMismatch(ValueError):
    """A message without the fields its template reads."""


def fill(template: Any, values: dict[str, Any]) -> Any:
    if is_placeholder(template):
        return values[template]
    if isinstance(template, dict):
        return {key: fill(value, values) for key, value in template.items()}
    if isinstance(template, list):
        return [fill(item, values) for item in template]
    return copy.copy(template)


def _holds_placeholder(template: Any) -> bool:
    if is_placeholder(template):
        return True
    if isinstance(template, dict):
        return any(_holds_placeholder(v) for v in template.values())
    if isinstance(template, list):
        return any(_holds_placeholder(v) for v in template)
    return False


def read(template: Any, message: Any, exact: bool = False, path: str = "") -> dict[str, Any]:
    """placeholder -> value found in `message`; with `exact`, fixed values must match too."""
    where = path or "the message"
    if is_placeholder(template):
        return {template: message}
    if isinstance(template, dict):
        if not isinstance(message, dict):
            raise TemplateMismatch(f"{where} is not a mapping")
        found = {}
        for key, value in template.items():
            below = f"{path}.{key}" if path else str(key)
            if key not in message:
                if exact or _holds_placeholder(value):
                    raise TemplateMismatch(f"lacks '{below}'")
                continue
            found.update(read(value, message[key], exact, below))
        return found
    if isinstance(template, list) and (exact or _holds_placeholder(template)):
        if not isinstance(message, list):
            raise TemplateMismatch(f"'{where}' is not a list")
        if len(message) != len(template):
            raise TemplateMismatch(f"'{where}' has {len(message)} items, expected {len(template)}")
        found = {}
        for index, (item, got) in enumerate(zip(template, message)):
            found.update(read(item, got, exact, f"{path}.{index}" if path else str(index)))
        return found
    if exact and message != template:
        raise TemplateMismatch(f"'{where}' is {message!r}, expected {template!r}")
    return {}
