"""How a command finds the robot or ID it is given: spec folders passed with --specs join the registry for that
command, robots are found through the IDs that use them, and an unknown name is answered with the nearest known
one and the three ways to make a folder of one's own known."""

from __future__ import annotations

from pathlib import Path

from envfactory.registration import registry
from envfactory.schema.compose import composed_config
from envfactory.schema.errors import SpecError, suggest

SPECS_SOURCE = "--specs"  # how a folder joined, as `registry.IdRecord.source` records it
HOW_TO_ADD = (
    f"if it is in a spec folder of your own, make the folder known: --specs PATH (this command), "
    f"`envfactory register PATH` (every later command) or {registry.SPEC_PATH_VARIABLE}=PATH (this shell)"
)


class MissingSpecFolder(ValueError):
    """A --specs path that is no folder."""


def register_spec_folders(folders: list[Path]) -> list[SpecError]:
    """Register the IDs of each folder for this process, as the import registers ENVFACTORY_SPEC_PATH (lazily:
    composing waits for the command); the problems of the families left out. A folder already registered
    (recorded, or on the variable) adds nothing and no clash."""
    missing = [folder for folder in folders if not folder.expanduser().is_dir()]
    if missing:
        raise MissingSpecFolder(
            "; ".join(f"--specs {folder}: {registry.not_a_folder(folder.expanduser())}" for folder in missing)
        )
    problems: list[SpecError] = []
    for folder in folders:
        problems += registry.register_folder(folder, source=SPECS_SOURCE)[1]
    return problems


def unknown_id(env_id: str) -> str | None:
    """For an ID no registered folder declares, the message naming the nearest ID and how to add a folder;
    None for a registered ID."""
    try:
        registry.record(env_id)
    except KeyError as exc:
        return f"{exc.args[0]}; {HOW_TO_ADD}"
    return None


def robot_ids() -> dict[str, list[str]]:
    """Every robot the registered families use, with their IDs (sorted). A family's robot comes from its
    defaults list, so one composition per family tells it; a family that does not compose is left out
    (`envfactory validate` names its problem)."""
    by_family: dict[Path, list[str]] = {}
    families = {}
    for env_id, entry in sorted(registry.records().items()):
        by_family.setdefault(entry.family.path, []).append(env_id)
        families[entry.family.path] = entry.family
    robots: dict[str, list[str]] = {}
    for path, ids in by_family.items():
        try:
            config, _ = composed_config(families[path])
        except SpecError:
            continue
        name = (config.get("robot") or {}).get("name")
        if isinstance(name, str):
            robots.setdefault(name, []).extend(ids)
    return {name: sorted(ids) for name, ids in sorted(robots.items())}


def robots_with_backend(backend: str) -> list[str]:
    """The robots with at least one ID on `backend` (rosbridge: the robots with a real path)."""
    records = registry.records()
    return [name for name, ids in robot_ids().items() if any(records[i].backend == backend for i in ids)]


def unknown_robot(name: str, robots: list[str], listed_as: str = "robots", ids: tuple[str, ...] = ()) -> str:
    """The message for a name that is none of `robots` (nor of `ids`, for a command taking either): the nearest
    of them, else the robots."""
    close = suggest(name, [*robots, *ids])
    hint = close if close.startswith(" (did you mean") else f" ({listed_as}: {', '.join(robots) or 'none'})"
    return f"no {'robot or ID' if ids else 'robot'} named {name!r}{hint}; {HOW_TO_ADD}"
