"""Where spec folders keep their files: the built-in folder, and the family files of any folder."""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path


def builtin_root() -> Path:
    """The folder holding robots/, tasks/ and specs/, installed or editable."""
    return Path(str(files("envfactory.specs"))).parent


def family_files(folder: Path) -> list[Path]:
    specs = folder / "specs" if (folder / "specs").is_dir() else folder
    return sorted(p for p in specs.glob("*.yaml") if not p.name.startswith("_") and p.is_file())


def folder_of(family_path: Path) -> Path:
    """The spec folder a family file belongs to (the parent of a specs/ subfolder)."""
    return family_path.parent.parent if family_path.parent.name == "specs" else family_path.parent


def search_roots(folder: Path) -> tuple[Path, ...]:
    """Where a folder's families look up robots/ and tasks/: itself, then the built-ins."""
    builtin = builtin_root()
    return (builtin,) if folder.resolve() == builtin.resolve() else (folder, builtin)
