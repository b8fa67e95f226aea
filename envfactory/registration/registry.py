"""Lazy registration of every env ID that the spec folders declare.

Importing the package only reads each family file's `registration` block;
composition and compilation wait for gym.make and are cached there. A user
folder can never break the import: a family file that cannot be read, or
whose IDs clash, is skipped whole with one warning line, and the built-in
IDs are registered first, always.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import gymnasium as gym
from gymnasium.envs.registration import ENV_ID_RE
from pydantic import ValidationError

from envfactory.registration import user_config, validation_cache
from envfactory.schema.compose import FamilyFile
from envfactory.schema.errors import Problem, SpecError, nearest, suggest
from envfactory.schema.folders import MAX_SPEC_BYTES, builtin_root, folder_of, list_folder, search_roots, unread_files
from envfactory.schema.models import Registration
from envfactory.schema.sources import Findings, SourceMap, load_plain
from envfactory.schema.validation import validation_problems

ENTRY_POINT = "envfactory.factory:make_env"  # gymnasium imports it at the first make
VECTOR_ENTRY_POINT = "envfactory.factory:make_vector_env"  # gym.make_vec's default: N envs in one process
SPEC_PATH_VARIABLE = "ENVFACTORY_SPEC_PATH"
# Bounded work: validating a family compiles each distinct ID, so their number is capped, as the family file's
# size is (schema.folders.MAX_SPEC_BYTES); both caps are stated in docs/concepts/specs-and-overrides.md
MAX_IDS_PER_FAMILY = 200
MAX_FAMILY_FILES = 500  # per folder

BUILTIN_SOURCE = "built-in"
CONFIG_SOURCE = "config"
ENVIRONMENT_SOURCE = SPEC_PATH_VARIABLE
CALL_SOURCE = "register_specs"

log = logging.getLogger("envfactory")


@dataclass(frozen=True)
class IdRecord:
    env_id: str
    family: FamilyFile
    backend: str
    goal_env: bool
    kwargs: tuple[tuple[str, Any], ...]
    max_episode_steps: int
    source: str = CALL_SOURCE  # how the folder joined: built-in, config, ENVFACTORY_SPEC_PATH, register_specs


_records: dict[str, IdRecord] = {}
FamilyCheck = Callable[[list[IdRecord], bool], None]  # (a family's fresh records, whether they are all of it)


# ------------------------------------------------------------------ scanning


def _id_problem(path: Path, env_id: str, message: str) -> Problem:
    sources = SourceMap()
    try:
        sources.record_file(path, "")
    except SpecError:
        pass
    return sources.problem(f"registration.ids.{env_id}", message)


def scan_family(path: Path, search_roots: tuple[Path, ...], source: str = CALL_SOURCE) -> list[IdRecord]:
    """The IDs one family file declares, from its registration block alone."""
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise SpecError([Problem("", f"cannot read: {exc.strerror}", str(path))], path.stem) from None
    if size > MAX_SPEC_BYTES:
        raise SpecError(
            [
                Problem(
                    "",
                    f"the file is {size / 1024:.0f} KiB; a spec file may hold at most "
                    f"{MAX_SPEC_BYTES // 1024} KiB (split the family)",
                    str(path),
                    1,
                )
            ],
            path.stem,
        )
    sources = SourceMap()
    sources.record_file(path, "")  # also refuses duplicate keys, which a plain load would merge silently
    data = load_plain(path)
    family = FamilyFile(path, search_roots)
    raw = data.get("registration")
    if raw is None:
        raise SpecError(
            [Problem("registration", "missing: a family must declare the IDs it registers", str(path), 1)], path.stem
        )
    found = Findings(sources)
    ids = raw.get("ids") if isinstance(raw, dict) else None
    if isinstance(ids, dict) and len(ids) > MAX_IDS_PER_FAMILY:
        found.add(
            "registration.ids",
            f"{len(ids)} IDs; a family may declare at most {MAX_IDS_PER_FAMILY} (split it into several files)",
        )
        found.raise_if_any(path.stem)
    try:
        registration = Registration.model_validate(raw)
    except ValidationError as exc:
        for problem in validation_problems(exc, sources, Registration):
            found.add(f"registration.{problem.path}" if problem.path else "registration", problem.message)
        found.raise_if_any(path.stem)
    for env_id in registration.ids:
        if not isinstance(env_id, str) or not ENV_ID_RE.fullmatch(env_id):
            found.add(
                f"registration.ids.{env_id}",
                f"{env_id!r} is not a valid gymnasium ID: use letters, digits, "
                f"'_', '-', '.', ':' and an optional 'ns/' prefix and '-v<N>' "
                f"suffix, e.g. 'MyReach-v0'",
            )
    found.raise_if_any(path.stem)
    return [
        IdRecord(
            env_id,
            family,
            entry.backend,
            entry.goal_env,
            tuple(sorted(entry.kwargs.items())),
            registration.max_episode_steps,
            source,
        )
        for env_id, entry in registration.ids.items()
    ]


def clash(record: IdRecord, pending: dict[str, IdRecord]) -> Problem | None:
    """The duplicate-ID problem of a record, naming both files and lines, or None."""
    existing = _records.get(record.env_id) or pending.get(record.env_id)
    if existing is not None and existing.family.path.resolve() != record.family.path.resolve():
        file, line = _location(existing.family.path, record.env_id)
        here = _id_problem(record.family.path, record.env_id, "")
        return Problem(
            here.path, f"duplicate env ID {record.env_id!r}: already declared at {file}:{line}", here.file, here.line
        )
    if existing is None and record.env_id in gym.registry:
        entry = gym.registry[record.env_id].entry_point
        return _id_problem(
            record.family.path,
            record.env_id,
            f"duplicate env ID {record.env_id!r}: gymnasium already has it (entry point {entry})",
        )
    return None


def _location(path: Path, env_id: str) -> tuple[str, int | None]:
    problem = _id_problem(path, env_id, "")
    return problem.file or str(path), problem.line


def _remembered_problem(path: Path, known: dict, stats) -> SpecError | None:
    """The problem an earlier check found in this family, if the family has not changed since."""
    remembered = validation_cache.recall(path, known, stats)
    if remembered is None or remembered[0]:
        return None
    problem = remembered[1]
    message = (
        f"{problem.get('message', 'invalid')} (found by an earlier validate or make; it registers again once "
        f"its folder changes or `envfactory validate {path}` passes)"
    )
    return SpecError(
        [Problem(str(problem.get("path") or ""), message, problem.get("file") or str(path), problem.get("line"))],
        path.stem,
    )


def _register_family(records: list[IdRecord]) -> None:
    """All of a family's IDs or none."""
    done = []
    try:
        for record in records:
            gym.register(
                id=record.env_id,
                entry_point=ENTRY_POINT,
                vector_entry_point=VECTOR_ENTRY_POINT,
                kwargs={"env_id": record.env_id},
                max_episode_steps=record.max_episode_steps,
            )
            done.append(record)
            _records[record.env_id] = record
    except Exception as exc:  # gymnasium's own checks: undo the family
        for record in done:
            gym.registry.pop(record.env_id, None)
            _records.pop(record.env_id, None)
        path = records[0].family.path
        raise SpecError(
            [Problem("registration.ids", f"gymnasium refused the IDs: {exc}", str(path))], path.stem
        ) from None


def register_folder(
    folder: str | Path, check: FamilyCheck | None = None, source: str = CALL_SOURCE
) -> tuple[list[str], list[SpecError]]:
    """Register every valid family in `folder`; return the new IDs and the problems of the rest.

    A family is registered whole or not at all. With a `check` (the factory's: compose and compile
    each ID as `make` would), each family passes it first; without one only the registration block
    is read, and a family an earlier check found broken stays out."""
    folder = Path(folder).expanduser()
    if not folder.is_dir():
        return [], [SpecError([Problem("", not_a_folder(folder), str(folder))])]
    roots = search_roots(folder)
    added = []
    pending: dict[str, IdRecord] = {}
    listing = list_folder(folder)
    paths = listing.families
    # a family file that is not read is never passed over silently: each is a problem of its own
    problems = [SpecError([Problem("", why, str(path))], path.stem) for path, why in unread_files(listing)]
    if not paths:
        return [], problems
    if len(paths) > MAX_FAMILY_FILES:
        return [], [
            SpecError(
                [
                    Problem(
                        "", f"{len(paths)} family files; a spec folder may hold at most {MAX_FAMILY_FILES}", str(folder)
                    )
                ]
            )
        ]
    # a user family that an earlier check found broken stays out whole (import composes nothing)
    remembered = validation_cache.read() if check is None and source != BUILTIN_SOURCE else None
    stats = validation_cache.folder_stats(folder_of(paths[0])) if remembered and paths else None
    for path in paths:
        try:
            records = scan_family(path, roots, source)
            clashes = [p for p in (clash(r, pending) for r in records) if p is not None]
            if clashes:
                raise SpecError(clashes, path.stem)
            fresh = [r for r in records if r.env_id not in _records]
            if check is not None and fresh:
                check(fresh, len(fresh) == len(records))
            elif remembered:
                broken = _remembered_problem(path, remembered, stats)
                if broken is not None:
                    raise broken
            _register_family(fresh)
        except SpecError as exc:
            problems.append(exc)
            continue
        pending.update({r.env_id: r for r in records})
        added += [r.env_id for r in fresh]
    return added, problems


def not_a_folder(path: Path) -> str:
    """Why a path given as a spec folder is none: a family file (name its folder), or nothing there."""
    if path.is_file():
        folder = folder_of(path)
        return (
            f"is a file, not a spec folder: spec folders are registered whole; give the folder that holds it, "
            f"{folder}" + (" (its family files are in specs/)" if path.parent.name == "specs" else "")
        )
    return f"no such spec folder{nearest_entry(path)}"


def nearest_entry(path: Path) -> str:
    """' (did you mean ...?)' among the entries beside a path that does not exist, or where the path stops existing."""
    parent = path.parent
    if not parent.is_dir():
        existing = next((p for p in path.parents if p.is_dir()), None)
        return f" ({parent} does not exist either{f'; {existing} does' if existing else ''})"
    close = nearest(path.name, (entry.name for entry in parent.iterdir()))
    return f" (did you mean {close!r}?)" if close else ""


def unregister_folder(folder: str | Path) -> list[str]:
    """Remove this process's IDs from a folder; the IDs removed."""
    folder = Path(folder).expanduser().resolve()
    gone = [env_id for env_id, r in _records.items() if folder_of(r.family.path).resolve() == folder]
    for env_id in gone:
        _records.pop(env_id)
        gym.registry.pop(env_id, None)
    return gone


# ------------------------------------------------------------------ on import


def environment_folders() -> list[Path]:
    return [Path(f) for f in os.environ.get(SPEC_PATH_VARIABLE, "").split(os.pathsep) if f]


def user_folders() -> list[tuple[Path, str]]:
    """Every user folder with how it joined: recorded by `envfactory register`, then the variable."""
    try:
        recorded = user_config.registered_folders()
    except user_config.ConfigError as exc:
        log.warning("envfactory: ignoring the config file: %s", exc)
        recorded = []
    return [*((f, CONFIG_SOURCE) for f in recorded), *((f, ENVIRONMENT_SOURCE) for f in environment_folders())]


def one_line(error: SpecError) -> str:
    """The first problem of a spec error on one line, with a count of the rest."""
    first = str(error.problems[0]) if error.problems else str(error)
    first = " ".join(first.split())
    more = len(error.problems) - 1
    return first + (f" (+{more} more)" if more > 0 else "")


def register_on_import() -> None:
    """Built-ins first, always; then every user folder, lazily, each bad file skipped with one warning."""
    _, problems = register_folder(builtin_root(), source=BUILTIN_SOURCE)
    for problem in problems:  # a broken installation: say so, never fail the import
        log.warning("envfactory: built-in spec skipped: %s", one_line(problem))
    for folder, source in user_folders():
        try:
            _, problems = register_folder(folder, source=source)
        except Exception as exc:  # never let a user folder break the import
            problems = [SpecError([Problem("", f"unreadable: {exc}", str(folder))])]
        for problem in problems:
            log.warning("envfactory: %s spec skipped: %s", source, one_line(problem))


# ------------------------------------------------------------------ lookups


def records() -> dict[str, IdRecord]:
    return dict(_records)


def record(env_id: str) -> IdRecord:
    try:
        return _records[env_id]
    except KeyError:
        raise KeyError(f"unknown env ID {env_id!r}{suggest(env_id, _records)}") from None
