"""Lazy registration of every env ID that the spec folders declare.

Importing the package only reads each family file's `registration` block;
composition and compilation wait for gym.make and are cached there.
"""

from __future__ import annotations

import functools
import os
import warnings
from dataclasses import dataclass
from importlib.resources import files
from pathlib import Path
from typing import Any, Iterable

import gymnasium as gym
from pydantic import ValidationError

from envfactory.spec.compose import FamilyFile, load_env_spec, validation_problems
from envfactory.spec.errors import Problem, SpecError
from envfactory.spec.schema import Registration
from envfactory.spec.sources import SourceMap, load_plain

ENTRY_POINT = "envfactory.registry:make_env"
SPEC_PATH_VARIABLE = "ENVFACTORY_SPEC_PATH"
# gym.make kwargs that configure the env object rather than the spec
ENV_OPTIONS = ("render_mode",)


@dataclass(frozen=True)
class IdRecord:
    env_id: str
    family: FamilyFile
    backend: str
    goal_env: bool
    kwargs: tuple[tuple[str, Any], ...]
    max_episode_steps: int


_records: dict[str, IdRecord] = {}
_reported: list[SpecError] = []


def builtin_root() -> Path:
    """The folder holding robots/, tasks/ and specs/, installed or editable."""
    return Path(str(files("envfactory.specs"))).parent


def family_files(folder: Path) -> list[Path]:
    specs = folder / "specs" if (folder / "specs").is_dir() else folder
    return sorted(p for p in specs.glob("*.yaml") if not p.name.startswith("_"))


def search_roots(folder: Path) -> tuple[Path, ...]:
    """Where a folder's families look up robots/ and tasks/: itself, then the built-ins."""
    builtin = builtin_root()
    return (builtin,) if folder.resolve() == builtin.resolve() else (folder, builtin)


def folder_of(family_path: Path) -> Path:
    """The spec folder a family file belongs to (the parent of a specs/ subfolder)."""
    return family_path.parent.parent if family_path.parent.name == "specs" else family_path.parent


def scan_family(path: Path, search_roots: tuple[Path, ...]) -> list[IdRecord]:
    """The IDs one family file declares, from its registration block alone."""
    data = load_plain(path)
    family = FamilyFile(path, search_roots)
    raw = data.get("registration")
    if raw is None:
        raise SpecError([Problem("registration", "missing: a family must declare the IDs it registers",
                                 str(path), 1)], path.stem)
    try:
        registration = Registration.model_validate(raw)
    except ValidationError as exc:
        sources = SourceMap()
        sources.record_file(path, "")
        problems = validation_problems(exc, sources, Registration)
        located = [sources.problem(f"registration.{p.path}" if p.path else "registration", p.message)
                   for p in problems]
        raise SpecError(located, path.stem) from None
    return [
        IdRecord(env_id, family, entry.backend, entry.goal_env, tuple(sorted(entry.kwargs.items())),
                 registration.max_episode_steps)
        for env_id, entry in registration.ids.items()
    ]


def _check_unique(record: IdRecord) -> None:
    existing = _records.get(record.env_id)
    if existing is not None and existing.family.path.resolve() != record.family.path.resolve():
        raise SpecError([Problem("registration.ids", f"duplicate env ID {record.env_id!r}: also declared in "
                                 f"{existing.family.path}", str(record.family.path))], record.env_id)


def _register(record: IdRecord) -> None:
    _records[record.env_id] = record
    gym.register(id=record.env_id, entry_point=ENTRY_POINT, kwargs={"env_id": record.env_id},
                 max_episode_steps=record.max_episode_steps)


def _check_family(records: list[IdRecord]) -> None:
    """Compose and compile each ID, so nothing invalid is registered."""
    from envfactory.compiler import compile_blueprint

    for record in records:
        loaded = load_env_spec(record.family, (), dict(record.kwargs))
        compile_blueprint(loaded, record.env_id, record.backend, record.goal_env)


def register_specs(folder: str | Path, validate: bool = True) -> tuple[list[str], list[SpecError]]:
    """Register every valid family in `folder`; return the new IDs and the problems of the rest."""
    folder = Path(folder).expanduser()
    if not folder.is_dir():
        error = SpecError([Problem("", "no such spec folder", str(folder))])
        return [], [error]
    roots = search_roots(folder)
    added, problems = [], []
    for path in family_files(folder):
        try:
            records = scan_family(path, roots)
            for record in records:
                _check_unique(record)
            if validate:
                _check_family(records)
        except SpecError as exc:
            problems.append(exc)
            continue
        for record in records:
            if record.env_id not in _records:
                _register(record)
                added.append(record.env_id)
    _reported.extend(problems)
    return added, problems


def register_builtin() -> None:
    register_specs(builtin_root(), validate=False)


def environment_folders() -> list[Path]:
    return [Path(f) for f in os.environ.get(SPEC_PATH_VARIABLE, "").split(os.pathsep) if f]


def register_from_environment() -> None:
    for folder in environment_folders():
        _, problems = register_specs(folder)
        for problem in problems:
            warnings.warn(f"{SPEC_PATH_VARIABLE}: {problem}", stacklevel=3)


def records() -> dict[str, IdRecord]:
    return dict(_records)


def reported_problems() -> list[SpecError]:
    return list(_reported)


def record(env_id: str) -> IdRecord:
    try:
        return _records[env_id]
    except KeyError:
        from envfactory.spec.errors import suggest

        raise KeyError(f"unknown env ID {env_id!r}{suggest(env_id, _records)}") from None


def _freeze(value: Any) -> Any:
    if isinstance(value, dict):
        return tuple(sorted((k, _freeze(v)) for k, v in value.items()))
    if isinstance(value, (list, tuple)):
        return tuple(_freeze(v) for v in value)
    return value


@functools.lru_cache(maxsize=128)
def _blueprint_cached(env_id: str, overrides: tuple[str, ...], frozen_kwargs: tuple, kwargs_items: tuple):
    from envfactory.compiler import compile_blueprint

    entry = record(env_id)
    loaded = load_env_spec(entry.family, overrides, dict(entry.kwargs), dict(kwargs_items))
    return compile_blueprint(loaded, env_id, entry.backend, entry.goal_env)


def blueprint(env_id: str, overrides: Iterable[str] = (), **kwargs):
    """The compiled blueprint of an ID, cached per (ID, overrides, kwargs)."""
    items = tuple(sorted(kwargs.items()))
    try:
        return _blueprint_cached(env_id, tuple(overrides), _freeze(kwargs), items)
    except TypeError:  # unhashable kwarg values: compile without the cache
        return _blueprint_cached.__wrapped__(env_id, tuple(overrides), (), items)


def make_env(env_id: str, overrides: Iterable[str] = (), render_mode: str | None = None, **kwargs):
    """The gym entry point of every registered ID."""
    from envfactory.envs import GoalRobotEnv, RobotEnv

    if isinstance(overrides, str):
        overrides = [overrides]
    compiled = blueprint(env_id, overrides, **kwargs)
    env_class = GoalRobotEnv if compiled.goal_env else RobotEnv
    return env_class(compiled, render_mode=render_mode)
