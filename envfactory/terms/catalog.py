"""Every term and expert with its params, size and unit: what `envfactory terms` prints."""

from __future__ import annotations

import sys
from types import SimpleNamespace
from typing import Iterator

from pydantic import BaseModel

from envfactory.experts import EXPERTS
from envfactory.terms import IMAGES, OBSERVATIONS, REWARDS, TERMINATIONS


def params_doc(model: type[BaseModel] | None) -> str:
    """`name: type = default [constraints]` for each param, or '-'."""
    if model is None or not model.model_fields:
        return "-"
    parts = []
    for name, field in model.model_fields.items():
        label = field.alias or name
        annotation = field.annotation
        kind = annotation.__name__ if isinstance(annotation, type) else str(annotation).replace("typing.", "")
        text = f"{label}: {kind}"
        if not field.is_required():
            text += f" = {field.default!r}"
        limits = [f"{op} {getattr(m, attr)}" for m in field.metadata for attr, op in
                  (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<=")) if getattr(m, attr, None) is not None]
        if limits:
            text += f" ({', '.join(limits)})"
        parts.append(text)
    return "; ".join(parts)


def _summary(function) -> str:
    """The docstring's first paragraph on one line (a first sentence may wrap over several lines)."""
    doc = (function.__doc__ or "").strip()
    return " ".join(doc.split("\n\n")[0].split())


def observation_rows() -> Iterator[tuple[str, ...]]:
    for name, term in sorted(OBSERVATIONS.items()):
        yield (name, term.size_doc, term.unit or "-", params_doc(term.params), "yes" if term.goal_dependent else "",
               _summary(term.fn))


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
