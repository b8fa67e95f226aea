"""Compose a family spec with Hydra, apply overrides and kwargs, validate it.

Order of precedence, lowest first: the defaults list of the family file,
then Hydra override strings, then the registered ID's kwargs, then the
caller's gym.make kwargs (each mapped onto a spec path by its alias).
"""

from __future__ import annotations

import copy
import functools
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable

import yaml
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException
from pydantic import ValidationError

from envfactory.schema import composed_store
from envfactory.schema.errors import Problem, SpecError, suggest
from envfactory.schema.folders import builtin_root, folder_of
from envfactory.schema.models import ComposedSpec
from envfactory.schema.numbers import non_finite_paths
from envfactory.schema.sources import Findings, SourceMap, load_plain, parse_yaml
from envfactory.schema.tree import leaves
from envfactory.schema.validation import validation_problems

MISSING = "???"
# Hydra's own packages a defaults entry may name: the including file's root, and the config's root
HYDRA_PACKAGES = ("_here_", "_global_")


@dataclass(frozen=True)
class FamilyFile:
    """A family spec file and the roots its defaults list searches."""

    path: Path
    search_roots: tuple[Path, ...]  # each may hold robots/, tasks/ and specs/

    @property
    def name(self) -> str:
        return self.path.stem

    @property
    def folder(self) -> Path:
        return folder_of(self.path)


@dataclass(frozen=True)
class Composed:
    config: dict
    sources: SourceMap


# ------------------------------------------------------------------ defaults


def _defaults_sources(family: FamilyFile, node: yaml.Node | None, sources: SourceMap) -> list[Problem]:
    """Record the files the defaults list pulls in, in merge order, and check they exist."""
    problems: list[Problem] = []
    entries = _defaults_entries(node)
    own_position = next((i for i, (group, _, _, _) in enumerate(entries) if group == "_self_"), len(entries))
    ordered = entries[:own_position] + [("_self_", None, None, None)] + entries[own_position + 1 :]
    for group, package, option, line in ordered:
        if group == "_self_":
            sources.record_file(family.path, "")
            continue
        relative = f"{group}/{option}.yaml" if option is not None else f"{group}.yaml"
        found = _find(relative.lstrip("/"), family)
        if found is None:
            what = group.strip("/").split("/")[-1]
            choices = (
                _options(group.strip("/"), family)
                if option is not None
                else [
                    f"{group.rsplit('/', 1)[0]}/{name}"
                    for name in _options(group.strip("/").rpartition("/")[0], family, shared=True)
                ]
            )
            label = f"{what} {option!r}" if option is not None else f"config {group!r}"
            problems.append(
                Problem("defaults", f"no {label} found{suggest(option or group, choices)}", str(family.path), line)
            )
            continue
        top = (package or "").split(".", 1)[0]
        if top and not top.startswith("_") and top not in ComposedSpec.model_fields:
            # Hydra would merge the file under a key no spec has: every value of it lost, reported as missing
            problems.append(
                Problem(
                    "defaults",
                    f"package {package!r} of {group}{f': {option}' if option else ''} "
                    f"names no part of a spec{suggest(top, ComposedSpec.model_fields)}; "
                    f"valid: {', '.join(ComposedSpec.model_fields)} or {' or '.join(HYDRA_PACKAGES)}",
                    str(family.path),
                    line,
                )
            )
            continue
        if package is not None and package.startswith("_") and package not in HYDRA_PACKAGES:
            problems.append(
                Problem(
                    "defaults",
                    f"package {package!r} of {group}: unknown{suggest(package, HYDRA_PACKAGES)}"
                    f"; valid: a part of a spec ({', '.join(ComposedSpec.model_fields)}) or "
                    f"{' or '.join(HYDRA_PACKAGES)}",
                    str(family.path),
                    line,
                )
            )
            continue
        if package is None or package in HYDRA_PACKAGES:
            sources.record_file(found, "")
        else:
            sources.record_choice(package, found, family.path, line)
            sources.record_file(found, package)
    return problems


def _defaults_entries(node: yaml.Node | None) -> list[tuple[str, str | None, str | None, int]]:
    if not isinstance(node, yaml.MappingNode):
        return []
    for key, value in node.value:
        if key.value == "defaults" and isinstance(value, yaml.SequenceNode):
            entries = []
            for item in value.value:
                line = item.start_mark.line + 1
                if isinstance(item, yaml.ScalarNode):
                    target, option = item.value, None
                elif isinstance(item, yaml.MappingNode) and len(item.value) == 1:
                    target, option = item.value[0][0].value, item.value[0][1].value
                else:
                    continue
                group, _, package = target.partition("@")
                entries.append((group, package or None, option, line))
            return entries
    return []


def _find(relative: str, family: FamilyFile) -> Path | None:
    if not relative.startswith("specs/"):
        local = family.path.parent / relative
        if local.is_file():
            return local
    for root in family.search_roots:
        candidate = root / relative
        if candidate.is_file():
            return candidate
    return None


def _options(group: str, family: FamilyFile, shared: bool = False) -> list[str]:
    """The configs a group offers; with `shared`, the underscored shared files too (a config path names those)."""
    names = set()
    for root in (family.path.parent, *family.search_roots):
        folder = root / group
        if folder.is_dir():
            names |= {p.stem for p in folder.glob("*.yaml") if shared or not p.stem.startswith("_")}
    return sorted(names)


# ------------------------------------------------------------------ hydra


def _hydra_compose(family: FamilyFile, overrides: tuple[str, ...]) -> DictConfig:
    from hydra import compose, initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    # A user's own Hydra app may hold the global instance: park it, compose,
    # and give it back, so building an env never disturbs the caller.
    global_hydra = GlobalHydra.instance()
    parked = global_hydra.hydra if global_hydra.is_initialized() else None
    if parked is not None:
        global_hydra.clear()
    try:
        roots = ",".join(f"'file://{root.resolve()}'" for root in family.search_roots)
        with initialize_config_dir(config_dir=str(family.path.parent.resolve()), version_base=None):
            return compose(config_name=family.name, overrides=[f"hydra.searchpath=[{roots}]", *overrides])
    finally:
        if parked is not None:
            GlobalHydra.instance().clear()
            GlobalHydra.instance().initialize(parked)


@functools.lru_cache(maxsize=64)
def _compose_cached(family: FamilyFile, overrides: tuple[str, ...]) -> Composed:
    """In this process, then on disk (composed_store.py), then by composing."""
    entry = composed_store.key(family.path, family.search_roots, overrides)
    stored = composed_store.load(entry)
    if isinstance(stored, Composed):
        return stored
    composed = _compose(family, overrides)
    composed_store.save(entry, composed)
    return composed


def _compose(family: FamilyFile, overrides: tuple[str, ...]) -> Composed:
    sources = SourceMap()
    node = parse_yaml(family.path)
    problems = _defaults_sources(family, node, sources)
    if problems:
        raise SpecError(problems, family.name)
    try:
        config = _hydra_compose(family, overrides)
    except Exception as exc:  # hydra raises several unrelated types
        unknown = _unknown_override_keys(family, overrides) if overrides else []
        if unknown:
            raise SpecError(unknown, family.name) from None
        message = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        where = f"override {list(overrides)}" if overrides else str(family.path)
        raise SpecError([Problem("", f"composition failed: {message}", where)], family.name) from None
    for override in overrides:
        key = override.split("=", 1)[0].lstrip("+~")
        sources.note(key, f"override {override!r}")
    return Composed(config=OmegaConf.to_container(config, resolve=False), sources=sources)


def _unknown_override_keys(family: FamilyFile, overrides: tuple[str, ...]) -> list[Problem]:
    """Each override whose key the spec lacks, with the nearest key at the level where the path left the
    spec (Hydra says only "Could not override"). Keys prefixed '+' add a key and are not checked."""
    config = _compose_cached(family, ()).config
    aliases = kwarg_aliases(config)
    problems = []
    for override in overrides:
        key, sep, _ = override.partition("=")
        if not sep or key.startswith("+"):
            continue
        node: Any = config
        walked: list[str] = []
        for part in key.lstrip("~").split("."):
            if isinstance(node, dict) and part in node:
                node, walked = node[part], walked + [part]
                continue
            if isinstance(node, list) and part.isdigit() and int(part) < len(node):
                node, walked = node[int(part)], walked + [part]
                continue
            where = ".".join(walked)
            keys = [f"{where}.{name}" if where else name for name in node] if isinstance(node, dict) else []
            if not walked:
                keys += list(aliases)  # a bare name may be a misspelled kwarg
            wrong = f"{where}.{part}" if where else part
            problems.append(
                Problem(
                    key,
                    f"no key {part!r} {f'under {where!r}' if where else 'at the top'} of the "
                    f"spec{suggest(wrong, keys)}: an override sets a key the spec has (a '+' before "
                    f"the key adds a new one)",
                    f"override {override!r}",
                )
            )
            break
    return problems


# ------------------------------------------------------------------ kwargs


def kwarg_aliases(config: dict) -> dict[str, str]:
    """Each gym.make kwarg's spec path: the shared defaults' aliases, then the task's own."""
    return {**config.get("kwargs", {}), **config.get("task", {}).get("kwargs", {})}


def apply_kwargs(
    config: dict, sources: SourceMap, kwargs: dict[str, Any], origin: str, written_at: str | None = None
) -> None:
    """Set each kwarg at the spec path its alias names. `written_at` is the dotted path of the
    mapping the kwargs were written in (a registration entry), so errors name its file and line."""
    aliases = kwarg_aliases(config)
    problems = []
    for name, value in kwargs.items():
        where = sources.locate(f"{written_at}.{name}") if written_at else Problem("", "", origin)
        file, line = (where.file, where.line) if where.line is not None else (origin, None)
        if name not in aliases:
            problems.append(
                Problem(
                    f"{written_at}.{name}" if written_at else "",
                    f"unknown kwarg {name!r}{suggest(name, aliases)}; valid kwargs: {', '.join(sorted(aliases))}",
                    file,
                    line,
                )
            )
            continue
        _set_path(config, aliases[name], value)
        if line is not None:  # errors at the aliased path point at where the kwarg was written
            sources.note(aliases[name], file, line)
        else:
            sources.note(aliases[name], f"{origin} {name}={value!r}")
    if problems:
        raise SpecError(problems)


def _kwarg_overrides(family: FamilyFile, overrides: tuple[str, ...]) -> tuple[tuple[str, ...], dict[str, Any]]:
    """Split `multi_goal=false`-style overrides (a kwarg name, no dots) from Hydra's own."""
    if not overrides:
        return overrides, {}
    config = _compose_cached(family, ()).config
    aliases = kwarg_aliases(config)
    hydra, kwargs = [], {}
    for override in overrides:
        key, sep, value = override.partition("=")
        if sep and key in aliases:
            try:
                kwargs[key] = yaml.safe_load(value)
            except yaml.YAMLError:
                kwargs[key] = value
        else:
            hydra.append(override)
    return tuple(hydra), kwargs


def _set_path(config: dict, dotted: str, value: Any) -> None:
    node = config
    *parents, leaf = dotted.split(".")
    for part in parents:
        node = node.setdefault(part, {})
    node[leaf] = value


# ------------------------------------------------------------------ validation


def _missing_paths(node: Any) -> Iterable[str]:
    return (path for path, value in leaves(node) if value == MISSING)


def _has_interpolation(node: Any) -> bool:
    return any(isinstance(value, str) and "${" in value for _, value in leaves(node))


def _resolve(config: dict, sources: SourceMap) -> dict:
    # OmegaConf wraps every node: on a family of many IDs that costs more than the rest
    # of loading, so it runs only when there is something to resolve
    if not _has_interpolation(config):
        return config
    try:
        return OmegaConf.to_container(OmegaConf.create(config), resolve=True)
    except OmegaConfBaseException as exc:
        path = getattr(exc, "full_key", "") or ""
        message = str(exc).splitlines()[0]
        raise SpecError([sources.problem(path, f"interpolation failed: {message}")]) from None


@dataclass(frozen=True)
class LoadedSpec:
    """A validated spec with the map back to where each value was written."""

    spec: ComposedSpec
    sources: SourceMap
    family: FamilyFile

    def findings(self) -> Findings:
        """An empty report of this spec's problems, placing each where its value was written."""
        return Findings(self.sources)

    def file_of(self, path: str) -> Path:
        shell = self.sources.locate(path)
        return Path(shell.file) if shell.file and shell.line is not None else self.family.path


def load_env_spec(
    family: FamilyFile,
    overrides: Iterable[str] = (),
    id_kwargs: dict[str, Any] | None = None,
    kwargs: dict[str, Any] | None = None,
    env_id: str | None = None,
) -> LoadedSpec:
    overrides, override_kwargs = _kwarg_overrides(family, tuple(overrides))
    composed = _compose_cached(family, overrides)
    config = copy.deepcopy(composed.config)
    sources = copy.deepcopy(composed.sources)
    try:
        if override_kwargs:
            apply_kwargs(config, sources, override_kwargs, "override")
        if id_kwargs:
            apply_kwargs(
                config, sources, id_kwargs, "registered kwarg", f"registration.ids.{env_id}.kwargs" if env_id else None
            )
        if kwargs:
            apply_kwargs(config, sources, kwargs, "gym.make kwarg")
    except SpecError as exc:
        raise SpecError(exc.problems, family.name) from None
    return validate_config(config, sources, family)


def composed_config(family: FamilyFile) -> tuple[dict, SourceMap]:
    """A private copy of the family's composed config (no overrides) and its source map."""
    composed = _compose_cached(family, ())
    return copy.deepcopy(composed.config), copy.deepcopy(composed.sources)


def validate_config(config: dict, sources: SourceMap, family: FamilyFile) -> LoadedSpec:
    """Validate a composed config (which this consumes) into a spec, or raise every problem at once."""
    # Report every ??? and every other problem in one go: drop the missing
    # keys so validation still runs, then keep one message per missing path.
    missing = list(_missing_paths(config))
    for path in missing:
        _delete_path(config, path)
    found = Findings(sources)
    for path in missing:
        found.add(path, "missing value (???)")
    resolved = _resolve(config, sources)
    resolved.pop("defaults", None)
    # NaN and infinity anywhere (term and expert params included) fail every comparison quietly
    non_finite = dict(non_finite_paths(resolved))
    for path, value in non_finite.items():
        found.add(path, f"Input should be a finite number (got {value})")
    skip = {*missing, *non_finite}
    spec = None
    try:
        spec = ComposedSpec.model_validate(resolved)
    except ValidationError as exc:
        found.problems += [p for p in validation_problems(exc, sources, ComposedSpec) if p.path not in skip]
    if found:
        found.problems = _placed(found.problems, family)
    found.raise_if_any(family.name)
    return LoadedSpec(spec, sources, family)


SHARED_DEFAULTS = "specs/_defaults"  # the built-in file of settings every family shares (scene, env, sim, kwargs)


def _placed(problems: list[Problem], family: FamilyFile) -> list[Problem]:
    """Problems at values no file wrote placed at the family's defaults list, which should have brought them in;
    a key the shared defaults set, in a family whose list lacks them, says to add that line."""
    if all(problem.file for problem in problems):
        return problems
    node = parse_yaml(family.path)
    line = (
        next((key.start_mark.line + 1 for key, _ in getattr(node, "value", ()) if key.value == "defaults"), 1)
        if isinstance(node, yaml.MappingNode)
        else 1
    )
    includes_shared = any(group.strip("/") == SHARED_DEFAULTS for group, _, _, _ in _defaults_entries(node))
    shared = load_plain(builtin_root() / f"{SHARED_DEFAULTS}.yaml")
    placed = []
    for problem in problems:
        if problem.file:
            placed.append(problem)
            continue
        top = problem.path.split(".", 1)[0]
        if top in shared and not includes_shared:
            why = (
                f"; no file of this defaults list sets {top!r}: the shared defaults do, and the list lacks "
                f"them: add '- /{SHARED_DEFAULTS}@_here_' to it"
            )
        else:
            why = f"; no file of this defaults list writes {problem.path!r}"
        placed.append(Problem(problem.path, problem.message + why, str(family.path), line))
    return placed


def _delete_path(config: dict, dotted: str) -> None:
    node: Any = config
    *parents, leaf = dotted.split(".")
    for part in parents:
        node = node[int(part)] if isinstance(node, list) else node[part]
    if isinstance(node, dict):
        del node[leaf]
