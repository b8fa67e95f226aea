"""Every term and expert with its params, size and unit: what `envfactory terms` prints."""

from __future__ import annotations

import sys
import types
import typing
from types import SimpleNamespace
from typing import Iterator

from pydantic import BaseModel

from envfactory.experts import EXPERTS
from envfactory.terms import EVENTS, IMAGES, OBSERVATIONS, REWARDS, SENSING, TERMINATIONS


def params_doc(model: type[BaseModel] | None) -> str:
    """`name: type = default [constraints]` for each param, or '-'."""
    if model is None or not model.model_fields:
        return "-"
    parts = []
    for name, field in model.model_fields.items():
        label = field.alias or name
        text = f"{label}: {type_name(field.annotation)}"
        if not field.is_required():
            text += f" = {field.default!r}"
        limits = [
            f"{op} {getattr(m, attr)}"
            for m in field.metadata
            for attr, op in (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<="))
            if getattr(m, attr, None) is not None
        ]
        if limits:
            text += f" ({', '.join(limits)})"
        parts.append(text)
    return "; ".join(parts)


def type_name(annotation) -> str:
    """A param's type as a spec writer reads it: `tuple[float, float] | None`, not the validators inside."""
    origin, arguments = typing.get_origin(annotation), typing.get_args(annotation)
    if origin is typing.Annotated:
        return type_name(arguments[0])
    if origin in (typing.Union, types.UnionType):
        return " | ".join(type_name(argument) for argument in arguments)
    if origin is typing.Literal:
        return f"Literal[{', '.join(repr(argument) for argument in arguments)}]"
    if origin is not None:
        return f"{getattr(origin, '__name__', str(origin))}[{', '.join(type_name(a) for a in arguments)}]"
    if annotation is type(None):
        return "None"
    return annotation.__name__ if isinstance(annotation, type) else str(annotation).replace("typing.", "")


def _summary(function) -> str:
    """The docstring's first paragraph on one line (a first sentence may wrap over several lines)."""
    doc = (function.__doc__ or "").strip()
    return " ".join(doc.split("\n\n")[0].split())


def observation_rows() -> Iterator[tuple[str, ...]]:
    for name, term in sorted(OBSERVATIONS.items()):
        yield (
            name,
            term.size_doc,
            term.unit or "-",
            params_doc(term.params),
            "yes" if term.goal_dependent else "",
            _summary(term.fn),
        )


def reward_rows() -> Iterator[tuple[str, ...]]:
    for name, term in sorted(REWARDS.items()):
        yield name, params_doc(term.params), ", ".join(term.info_keys) or "-", term.description


def termination_rows() -> Iterator[tuple[str, ...]]:
    for name, term in sorted(TERMINATIONS.items()):
        yield name, params_doc(term.params), ", ".join(term.info_keys) or "-", term.description


def image_rows() -> Iterator[tuple[str, ...]]:
    symbolic = SimpleNamespace(height="height", width="width", far="far")  # scene.camera's fields by name
    for name, term in sorted(IMAGES.items()):
        shape = " × ".join(map(str, term.shape(symbolic)))
        yield name, shape, term.dtype.__name__, term.description


def expert_rows() -> Iterator[tuple[str, ...]]:
    for name, expert in sorted(EXPERTS.items()):
        yield name, params_doc(expert.Params), _summary(sys.modules[expert.__module__])


def event_rows() -> Iterator[tuple[str, ...]]:
    for name, term in sorted(EVENTS.items()):
        yield name, term.unit or "-", params_doc(term.params), _summary(term.fn)


def sensing_rows() -> Iterator[tuple[str, ...]]:
    for name, term in sorted(SENSING.items()):
        yield name, term.unit or "-", params_doc(term.params), _summary(term.fn)


# What `envfactory terms` prints and the docs' terms page renders: (title, columns, rows)
TABLES = [
    (
        "Observation terms (task.observation)",
        ("Name", "Size", "Unit", "Params", "Goal-dependent", "Meaning"),
        observation_rows,
    ),
    (
        "Reward terms (task.reward.sparse / dense: {term, weight, params})",
        ("Name", "Params", "Reads info", "Meaning"),
        reward_rows,
    ),
    (
        "Termination terms (task.termination: {term, params, when})",
        ("Name", "Params", "Reads info", "Meaning"),
        termination_rows,
    ),
    ("Image terms (scene.camera.terms, with use_kinect)", ("Name", "Shape", "Dtype", "Meaning"), image_rows),
    (
        "Event terms (task.randomization.events: {term, every, params})",
        ("Name", "Unit", "Params", "Samples"),
        event_rows,
    ),
    ("Sensing terms (task.randomization.sensing: {term, params})", ("Name", "Unit", "Params", "Does"), sensing_rows),
    ("Experts (task.expert: {policy, params})", ("Name", "Params", "What it does"), expert_rows),
]
