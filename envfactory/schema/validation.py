"""Pydantic's validation errors as located problems: each names its dotted path, the file and line
where the value was written, and the nearest valid key for an unknown one."""

from __future__ import annotations

from typing import Any, get_args, get_origin

from pydantic import BaseModel, ValidationError

from envfactory.schema.base import split_located
from envfactory.schema.errors import Problem, suggest
from envfactory.schema.sources import SourceMap
from envfactory.schema.units import kind_of, unit_hint

# pydantic's range errors and the context key of the bound each one broke
RANGE_ERRORS = {"less_than_equal": "le", "less_than": "lt", "greater_than_equal": "ge", "greater_than": "gt"}


def _fields_at(model: type[BaseModel], loc: tuple) -> list[str]:
    """Field names of the model found at `loc` under `model`, for suggestions."""
    current: Any = model
    for part in loc:
        if isinstance(current, type) and issubclass(current, BaseModel):
            field = current.model_fields.get(str(part))
            if field is None:
                return []
            current = field.annotation
        elif get_origin(current) in (dict, list, tuple):
            current = get_args(current)[-1]
        else:
            return []
        while get_origin(current) is not None and get_origin(current) not in (dict, list, tuple):
            args = [a for a in get_args(current) if a is not type(None)]
            current = args[0] if args else current
    if isinstance(current, type) and issubclass(current, BaseModel):
        return list(current.model_fields)
    return []


def validation_problems(exc: ValidationError, sources: SourceMap, model: type[BaseModel]) -> list[Problem]:
    problems = []
    for error in exc.errors():
        loc = tuple(part for part in error["loc"] if not str(part).startswith("function-"))
        path = ".".join(str(part) for part in loc)
        message = error["msg"].removeprefix("Value error, ")
        below, message = split_located(message)
        if below:
            loc, path = loc + tuple(below.split(".")), ".".join(filter(None, [path, below]))
        if error["type"] == "extra_forbidden":
            message = f"unknown key {loc[-1]!r}{suggest(str(loc[-1]), _fields_at(model, loc[:-1]))}"
        elif error["type"] == "missing":
            message = "missing value"
        elif "input" in error and not below and not isinstance(error["input"], (dict, list)):
            message += f" (got {error['input']!r}{_range_hint(error, path)})"
        problems.append(sources.problem(path, message))
    return problems


def _range_hint(error: dict, path: str) -> str:
    """A range error's unit hint (degrees for radians, centimetres for metres), or ''."""
    bound_key = RANGE_ERRORS.get(error["type"])
    value, bound = error.get("input"), (error.get("ctx") or {}).get(bound_key)
    if (
        bound_key is None
        or isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not isinstance(bound, (int, float))
    ):
        return ""
    return unit_hint(float(value), float(bound), kind_of(path))
