"""ROS message templates: the shape of each message on the wire, declared in YAML.

A template is the message itself with placeholders where the values go. The
shipped ones live in robots/_messages.yaml; a robot may name one of them or
write its own in place. Both sides fill and read the same template: the
rosbridge backend, and the digital twin that stands in for the robot.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

from pydantic import ValidationError, model_validator

from envfactory.schema.base import Model, located, split_located
from envfactory.schema.errors import Problem, SpecError, suggest
from envfactory.schema.folders import builtin_root
from envfactory.schema.sources import SourceMap, load_plain
from envfactory.schema.validation import validation_problems

# The placeholders each kind of message may hold, and those it must hold.
PLACEHOLDERS: dict[str, set[str]] = {
    "arm": {"$joint_names", "$positions", "$zeros", "$duration", "$group"},
    "gripper": {"$value", "$state", "$name", "$goal_id"},
    "joint_state": {"$joint_names", "$positions", "$velocities", "$stamp"},
    "pose": {"$frame_id", "$stamp", "$x", "$y", "$z", "$qx", "$qy", "$qz", "$qw"},
}
REQUIRED: dict[str, set[str]] = {
    "arm": {"$positions"},
    "gripper": set(),
    "joint_state": {"$joint_names", "$positions"},
    "pose": {"$x", "$y", "$z", "$qx", "$qy", "$qz", "$qw"},
}
# Exactly one of these: a gripper takes a position ($value), or only opens and closes ($state).
ONE_OF: dict[str, set[str]] = {"gripper": {"$value", "$state"}}
ALL_PLACEHOLDERS = set().union(*PLACEHOLDERS.values())
LIBRARY_FILE = "_messages.yaml"  # in the built-in robots folder


def is_placeholder(value: Any) -> bool:
    return isinstance(value, str) and value.startswith("$")


def placeholder_paths(template: Any, prefix: str = "") -> dict[str, str]:
    """placeholder -> dotted path where the template holds it."""
    found: dict[str, str] = {}
    items = (
        template.items() if isinstance(template, dict) else enumerate(template) if isinstance(template, list) else ()
    )
    for key, value in items:
        path = f"{prefix}.{key}" if prefix else str(key)
        if is_placeholder(value):
            found.setdefault(value, path)
        else:
            found.update({k: v for k, v in placeholder_paths(value, path).items() if k not in found})
    return found


def _repeats(template: Any, prefix: str = "", seen: set | None = None) -> list[tuple[str, str]]:
    seen = set() if seen is None else seen
    repeats = []
    items = (
        template.items() if isinstance(template, dict) else enumerate(template) if isinstance(template, list) else ()
    )
    for key, value in items:
        path = f"{prefix}.{key}" if prefix else str(key)
        if is_placeholder(value):
            if value in seen and value != "$zeros":
                repeats.append((path, value))
            seen.add(value)
        else:
            repeats += _repeats(value, path, seen)
    return repeats


class MessageTemplate(Model):
    type: str | None = None  # the ROS type it is a message of; checked against the topic's type
    message: dict[str, Any]
    stop: dict[str, Any] | None = None  # arm commands only: the message that stops the arm where it is

    @model_validator(mode="after")
    def _placeholders_known(self) -> "MessageTemplate":
        for part in ("message", "stop"):
            template = getattr(self, part)
            if template is None:
                continue
            for name, path in placeholder_paths(template).items():
                if name not in ALL_PLACEHOLDERS:
                    raise located(f"{part}.{path}", f"unknown placeholder {name!r}{suggest(name, ALL_PLACEHOLDERS)}")
            for path, name in _repeats(template):
                raise located(f"{part}.{path}", f"placeholder {name} appears twice: a value is read from one place")
        return self

    def placeholders(self, part: str = "message") -> set[str]:
        template = getattr(self, part)
        return set() if template is None else set(placeholder_paths(template))

    def role_problem(self, role: str) -> tuple[str, str] | None:
        """(path below the template, message) if it cannot serve as this kind of message."""
        for part in ("message", "stop"):
            wrong = sorted(self.placeholders(part) - PLACEHOLDERS[role])
            if wrong:
                path = placeholder_paths(getattr(self, part))[wrong[0]]
                return (
                    f"{part}.{path}",
                    f"placeholder {wrong[0]} has no meaning in {_kind(role)} "
                    f"message (valid: {', '.join(sorted(PLACEHOLDERS[role]))})",
                )
        missing = sorted(REQUIRED[role] - self.placeholders())
        if missing:
            return ("message", f"{_kind(role)} message needs the placeholder(s) {', '.join(missing)}")
        alternatives = ONE_OF.get(role, set())
        if alternatives and len(alternatives & self.placeholders()) != 1:
            return (
                "message",
                f"{_kind(role)} message needs exactly one of the placeholders {' or '.join(sorted(alternatives))}",
            )
        if self.stop is not None and role != "arm":
            return ("stop", "only an arm command has a stop message")
        return None


def _library_path() -> Path:
    return builtin_root() / "robots" / LIBRARY_FILE


@functools.lru_cache(maxsize=1)
def library() -> dict[str, MessageTemplate]:
    """The shipped templates by name; a broken file is a SpecError naming its file, line and path."""
    path = _library_path()
    sources = SourceMap()
    sources.record_file(path, "")
    data = load_plain(path)
    templates, problems = {}, []
    for name, body in data.items():
        try:
            templates[str(name)] = MessageTemplate.model_validate(body)
        except ValidationError as exc:
            shifted = SourceMap(
                locations={
                    key.removeprefix(f"{name}."): where
                    for key, where in sources.locations.items()
                    if key.startswith(f"{name}.")
                }
            )
            problems += [
                Problem(f"{name}.{p.path}", p.message, p.file, p.line)
                for p in validation_problems(exc, shifted, MessageTemplate)
            ]
    if problems:
        raise SpecError(problems, LIBRARY_FILE)
    return templates


def resolve(encoding: "str | dict") -> MessageTemplate:
    """The template an `encoding` names or writes; KeyError for an unknown name, ValidationError
    for a template that does not validate."""
    if isinstance(encoding, dict):
        return MessageTemplate.model_validate(encoding)
    known = library()
    if encoding not in known:
        raise KeyError(f"no message template {encoding!r} in {LIBRARY_FILE}{suggest(encoding, known)}")
    return known[encoding]


def _kind(role: str) -> str:
    words = role.replace("_", " ")
    return f"{'an' if words[0] in 'aeiou' else 'a'} {words}"


def checked(encoding: "str | dict", role: str) -> MessageTemplate:
    """The template `encoding` names or writes, if it serves this role; else a located ValueError."""
    try:
        template = resolve(encoding)
    except KeyError as exc:
        raise located(
            "encoding", str(exc.args[0]) + " (or write the template in place: {type: ..., message: {...}})"
        ) from None
    except SpecError as exc:
        raise located(
            "encoding", "the shipped templates are broken: " + "; ".join(str(problem) for problem in exc.problems)
        ) from None
    except ValidationError as exc:
        error = sorted(exc.errors(), key=lambda e: e["type"] != "extra_forbidden")[0]  # a typo explains a missing key
        below, message = split_located(error["msg"].removeprefix("Value error, "))
        loc = ".".join(str(part) for part in error["loc"] if not str(part).startswith("function-"))
        if error["type"] == "extra_forbidden":
            message = f"unknown key {error['loc'][-1]!r} (valid: type, message, stop)"
        elif error["type"] == "missing":
            message = "missing value"
        raise located(".".join(filter(None, ["encoding", loc, below])), message) from None
    problem = template.role_problem(role)
    if problem is not None:
        below, message = problem
        where = f"encoding.{below}" if isinstance(encoding, dict) else "encoding"
        prefix = "" if isinstance(encoding, dict) else f"template {encoding!r}: "
        raise located(where, prefix + message)
    return template
