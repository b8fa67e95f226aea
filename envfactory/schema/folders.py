"""Where spec folders keep their files: the built-in folder, and the family files of any folder."""

from __future__ import annotations

import re
from dataclasses import dataclass
from importlib.resources import files
from pathlib import Path

FAMILY_SUFFIX = ".yaml"
# A family file declares the IDs it registers; a shared file (defaults, a robot, a task) never does.
_DECLARES_IDS = re.compile(r"^registration\s*:", re.MULTILINE)
# Bounded work: a family file is read whole at import (and sniffed for its registration block), so its size is
# capped; the registry refuses a larger one, naming the cap (docs: concepts/specs-and-overrides)
MAX_SPEC_BYTES = 256 * 1024


def builtin_root() -> Path:
    """The folder holding robots/, tasks/ and specs/, installed or editable."""
    return Path(str(files("envfactory.specs"))).parent


@dataclass(frozen=True)
class FolderListing:
    """What a spec folder holds: its family files, and every YAML file that is not read as one, with why."""

    folder: Path
    families: list[Path]
    skipped: list[tuple[Path, str]]  # not read, by the folder's conventions
    lost: list[tuple[Path, str]]  # not read although they declare IDs: a family the user means to register

    @property
    def family_folder(self) -> Path:
        return family_home(self.folder)


def family_home(folder: Path) -> Path:
    """Where a folder keeps its family files: its specs/ folder if it has one, else the folder itself."""
    return folder / "specs" if (folder / "specs").is_dir() else folder


def list_folder(folder: Path) -> FolderListing:
    specs, home = folder / "specs", family_home(folder)
    families, skipped, lost = [], [], []
    for path in sorted(p for p in home.iterdir() if p.is_file()):
        if path.suffix == FAMILY_SUFFIX and not path.name.startswith("_"):
            families.append(path)
        elif path.suffix in (".yaml", ".yml"):
            reason = _why_skipped(path)
            # a leading underscore is the way to keep a file out; a .yml extension never is
            (lost if path.suffix == ".yml" and _declares_ids(path) else skipped).append((path, reason))
    if home == specs:
        for path in sorted(
            p for p in folder.iterdir() if p.suffix in (".yaml", ".yml") and p.is_file() and _declares_ids(p)
        ):
            lost.append(
                (
                    path,
                    f"a family file at the folder's root is not read: {folder} has a specs/ folder, "
                    f"and only the family files in it are read; move it into {specs}",
                )
            )
    return FolderListing(folder, families, skipped, lost)


def unread_files(listing: FolderListing) -> list[tuple[Path, str]]:
    """What registering the folder would pass over, as (path, why): with families, each file that declares IDs
    but is not read; with none, the folder itself, saying which files were skipped and why (or that it is empty)."""
    if listing.families:
        return listing.lost
    home = listing.family_folder
    skipped = sorted(listing.lost + listing.skipped)
    if skipped:
        listed = "; ".join(f"{path.relative_to(listing.folder)}: {why}" for path, why in skipped)
        return [(listing.folder, f"no family files (*{FAMILY_SUFFIX}) to read in {home}; skipped {listed}")]
    if not any(listing.folder.iterdir()):
        return [
            (
                listing.folder,
                f"the folder is empty: a spec folder holds family files (*{FAMILY_SUFFIX}, each "
                f"declaring registration.ids) in a specs/ folder or at its root, and the robots/ and "
                f"tasks/ they name",
            )
        ]
    return [(listing.folder, f"no family files (*{FAMILY_SUFFIX}) in {home}: it holds no YAML file")]


def _why_skipped(path: Path) -> str:
    if path.name.startswith("_"):
        return (
            "a leading underscore marks a shared file that families include through their defaults list "
            "(as specs/_defaults.yaml), never a family of its own"
        )
    return f"family files end in {FAMILY_SUFFIX}: rename it to {path.with_suffix(FAMILY_SUFFIX).name}"


def _declares_ids(path: Path) -> bool:
    try:
        with open(path, encoding="utf-8", errors="replace") as handle:
            return bool(_DECLARES_IDS.search(handle.read(MAX_SPEC_BYTES)))
    except OSError:
        return False


def family_files(folder: Path) -> list[Path]:
    return list_folder(folder).families


def folder_of(family_path: Path) -> Path:
    """The spec folder a family file belongs to (the parent of a specs/ subfolder)."""
    return family_path.parent.parent if family_path.parent.name == "specs" else family_path.parent


def search_roots(folder: Path) -> tuple[Path, ...]:
    """Where a folder's families look up robots/ and tasks/: itself, then the built-ins."""
    builtin = builtin_root()
    return (builtin,) if folder.resolve() == builtin.resolve() else (folder, builtin)
