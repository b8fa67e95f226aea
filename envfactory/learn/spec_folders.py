"""The spec folder a run's ID comes from, recorded with the run (model.json's `spec_folder`), so that a later
`train --resume` or `run --policy` in a new process finds a user's ID without being told the folder again."""

from __future__ import annotations

from pathlib import Path

from envfactory.factory import register_specs
from envfactory.learn.runs import RunFolderError
from envfactory.registration import registry
from envfactory.registration.registry import BUILTIN_SOURCE
from envfactory.schema.folders import folder_of


def recorded_folder(env_id: str) -> str | None:
    """The user spec folder that declares `env_id`; None for a built-in ID."""
    record = registry.record(env_id)
    return None if record.source == BUILTIN_SOURCE else str(folder_of(Path(record.family.path)))


def register_recorded(data: dict, where: Path) -> None:
    """Register the spec folder a run recorded, when its ID is not known in this process."""
    env_id, folder = data["env_id"], data.get("spec_folder")
    if env_id in registry.records() or not folder:
        return
    if not Path(folder).is_dir():
        raise RunFolderError(f"{where}: its ID {env_id} comes from the spec folder {folder}, which is gone")
    _, problems = register_specs(folder)
    if env_id not in registry.records():
        why = f": {problems[0]}" if problems else ""
        raise RunFolderError(f"{where}: its ID {env_id} is no longer declared by its spec folder {folder}{why}")
