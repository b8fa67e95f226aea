"""Folders that travel to the workers with the work: a user's spec folder, a trained model's files.

A worker may run on another machine, with another working folder and other environment variables than the
head's, so nothing reaches it by a relative path, ENVFACTORY_SPEC_PATH or a folder recorded by `envfactory
register`. The head packs the folder's files into a `FolderCopy` (sent once per job in the task's arguments)
and the worker calls `where()`: the folder itself when that path holds the same files (the same machine, or a
filesystem every node mounts), else a copy written once per machine under the temporary folder, named by the
files' digest.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

CACHE_FOLDER = "envfactory-cluster"  # under the worker's temporary folder
MAX_BYTES = 512 * 1024 * 1024  # a spec folder holds YAML, URDFs and meshes: more than this is a mistake
SKIPPED = ("__pycache__",)  # byte code is rebuilt where the folder lands


class FolderCopyError(ValueError):
    """A folder that cannot travel: missing, or too large."""


@dataclass(frozen=True)
class FolderCopy:
    origin: str  # the folder's absolute path on the head
    files: tuple[tuple[str, bytes], ...]  # (path relative to the folder, content), sorted by path
    digest: str

    @classmethod
    def pack(cls, folder: str | Path, names: tuple[str, ...] | None = None) -> "FolderCopy":
        """Every file under `folder` (hidden entries and byte code left out), or only the top-level files
        `names` that exist."""
        folder = Path(folder).expanduser().resolve()
        if not folder.is_dir():
            raise FolderCopyError(f"{folder}: no such folder to send to the workers")
        if names is None:
            paths = [p for p in folder.rglob("*") if p.is_file() and not _skipped(p.relative_to(folder))]
        else:
            paths = [folder / name for name in names if (folder / name).is_file()]
        total = sum(p.stat().st_size for p in paths)
        if total > MAX_BYTES:
            raise FolderCopyError(
                f"{folder}: {total / 1e6:.0f} MB of files, more than the {MAX_BYTES / 1e6:.0f} MB "
                f"a folder may send to the workers"
            )
        files = tuple(sorted((p.relative_to(folder).as_posix(), p.read_bytes()) for p in paths))
        return cls(str(folder), files, _digest(files))

    def where(self) -> Path:
        """The folder with these files on this machine: the origin when it holds them, else a copy."""
        origin = Path(self.origin)
        if origin.is_dir() and self._matches(origin):
            return origin
        copy = Path(tempfile.gettempdir()) / CACHE_FOLDER / self.digest / origin.name
        if not copy.is_dir():
            self._write(copy)
        return copy

    def _matches(self, folder: Path) -> bool:
        try:
            found = tuple((name, (folder / name).read_bytes()) for name, _ in self.files)
        except OSError:
            return False
        return _digest(found) == self.digest

    def _write(self, copy: Path) -> None:
        # written beside, then renamed into place: two workers on one machine never see half a copy
        staging = Path(tempfile.mkdtemp(prefix=".staging-", dir=_made(copy.parent)))
        for name, content in self.files:
            target = staging / name
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(content)
        try:
            os.rename(staging, copy)
        except OSError:  # another worker got there first with the same files
            shutil.rmtree(staging, ignore_errors=True)
            if not copy.is_dir():
                raise


def _skipped(relative: Path) -> bool:
    return any(part.startswith(".") or part in SKIPPED for part in relative.parts)


def _digest(files: tuple[tuple[str, bytes], ...]) -> str:
    digest = hashlib.sha256()
    for name, content in files:
        digest.update(name.encode() + b"\0" + len(content).to_bytes(8, "little") + content)
    return digest.hexdigest()[:16]


def _made(folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    return folder
