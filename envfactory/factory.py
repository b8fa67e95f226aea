"""From an env ID to a blueprint and an env: compose and compile on demand, cached per (ID, overrides,
kwargs); validate a folder's families before they register. gymnasium's entry point of every ID."""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any, Iterable

from gymnasium.vector import AutoresetMode

from envfactory.compiler import compile_blueprint
from envfactory.envs.robot_env import env_for
from envfactory.envs.vector_env import RobotVectorEnv, vector_env
from envfactory.registration import registry, validation_cache
from envfactory.registration.registry import BUILTIN_SOURCE, CALL_SOURCE, IdRecord
from envfactory.schema.compose import composed_config, kwarg_aliases, load_env_spec
from envfactory.schema.errors import SpecError


def register_specs(
    folder: str | Path, validate: bool = True, source: str = CALL_SOURCE
) -> tuple[list[str], list[SpecError]]:
    """Register every valid family in `folder`; return the new IDs and the problems of the rest. With
    `validate` each ID is composed and compiled first, as `make` would; a family registers whole or not at all."""
    return registry.register_folder(folder, check_family if validate else None, source)


def unregister_folder(folder: str | Path) -> list[str]:
    """Remove this process's IDs from a folder, and every blueprint compiled from them; the IDs removed."""
    gone = registry.unregister_folder(folder)
    _blueprint_cached.cache_clear()
    return gone


def check_family(records: list[IdRecord], whole: bool = True) -> None:
    """Compose and compile each distinct ID, so nothing invalid is registered. IDs that differ
    only in name compile alike, so each (backend, goal_env, kwargs) is compiled once. The verdict
    is remembered for later imports (`whole`: the records are all the family declares)."""
    seen = set()
    try:
        for record in records:
            key = (record.backend, record.goal_env, repr(record.kwargs))
            if key in seen:
                continue
            seen.add(key)
            loaded = load_env_spec(record.family, (), dict(record.kwargs), env_id=record.env_id)
            compile_blueprint(loaded, record.env_id, record.backend, record.goal_env)
    except SpecError as exc:
        if records:
            _remember_failure(records[0], exc)
        raise
    if records and whole:
        validation_cache.remember(records[0].family.path, True)


# Problems that are not the family's to remember as broken: one a command fixes without editing the family (its
# IDs must stay registered for that command: `envfactory collision-pairs ROBOT` finds the robot through them),
# and one of this machine rather than the folder (a GUI without a display works on the next machine).
_NOT_THE_FAMILYS = {"robot.safety.collision_pairs", "env.gui"}


def _remember_failure(record: IdRecord, error: SpecError) -> None:
    if record.source == BUILTIN_SOURCE or not error.problems:
        return
    if all(problem.path in _NOT_THE_FAMILYS for problem in error.problems):
        return
    # the family's own line first: that is where the user looks
    own = [p for p in error.problems if p.file and Path(p.file).resolve() == record.family.path.resolve()]
    first = (own or error.problems)[0]
    validation_cache.remember(
        record.family.path,
        False,
        {"path": first.path, "message": first.message, "file": first.file, "line": first.line},
    )


def _freeze(value: Any) -> Any:
    if isinstance(value, dict):
        return tuple(sorted((k, _freeze(v)) for k, v in value.items()))
    if isinstance(value, (list, tuple)):
        return tuple(_freeze(v) for v in value)
    return value


@functools.lru_cache(maxsize=128)
def _blueprint_cached(env_id: str, overrides: tuple[str, ...], frozen_kwargs: tuple, kwargs_items: tuple):
    entry = registry.record(env_id)
    try:
        loaded = load_env_spec(entry.family, overrides, dict(entry.kwargs), dict(kwargs_items), env_id=env_id)
        return compile_blueprint(loaded, env_id, entry.backend, entry.goal_env)
    except SpecError as exc:
        if not overrides and not kwargs_items:  # the ID as registered: the family itself is broken
            _remember_failure(entry, exc)
        raise


def blueprint(env_id: str, overrides: str | Iterable[str] = (), **kwargs):
    """The compiled blueprint of an ID, cached per (ID, overrides, kwargs); one override may come as a string."""
    overrides = (overrides,) if isinstance(overrides, str) else tuple(overrides)
    items = tuple(sorted(kwargs.items()))
    try:
        return _blueprint_cached(env_id, overrides, _freeze(kwargs), items)
    except TypeError:  # unhashable kwarg values: compile without the cache
        return _blueprint_cached.__wrapped__(env_id, overrides, (), items)


def make_env(env_id: str, overrides: str | Iterable[str] = (), render_mode: str | None = None, **kwargs):
    """The gym entry point of every registered ID."""
    return env_for(blueprint(env_id, overrides, **kwargs), render_mode)


def make_vector_env(
    env_id: str,
    num_envs: int = 1,
    overrides: str | Iterable[str] = (),
    render_mode: str | None = None,
    max_episode_steps: int | None = None,
    autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
    **kwargs,
) -> RobotVectorEnv:
    """The gym vector entry point of every registered ID: `num_envs` envs in this process, on one blueprint
    (gym.make_vec passes the ID's time limit as `max_episode_steps`)."""
    return vector_env(blueprint(env_id, overrides, **kwargs), num_envs, max_episode_steps, autoreset_mode, render_mode)


# What only a simulator has: its engine, rate and fidelity, and the sampled physics and imitated sensing of
# randomization. A model trained in simulation carries these kwargs; its Real ID runs without them.
SIMULATION_ONLY_PATHS = ("sim.", "task.randomization.enabled")


def simulation_only_kwargs(env_id: str, kwargs: dict[str, Any]) -> list[str]:
    """The kwargs that set, in the ID's family, something only a simulator has."""
    config, _ = composed_config(registry.records()[env_id].family)
    aliases = kwarg_aliases(config)
    return sorted(
        name for name in kwargs if any(aliases.get(name, "").startswith(prefix) for prefix in SIMULATION_ONLY_PATHS)
    )
