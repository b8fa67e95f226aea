"""A training run's folder and its record.

A run never writes into a folder that holds an earlier run: `fresh_folder`
picks the first free `NAME`, `NAME-2`, `NAME-3`... and `claim` refuses a
taken one (two runs started at once cannot both get it). The record,
`model.json`, says everything that shaped the run and every part of it: a run
continued with `--resume` adds a part, so the chain of parts stays readable.
"""

from __future__ import annotations

import json
import os
import platform
import shutil
from dataclasses import dataclass
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path

from envfactory.version import __version__

RECORD_FILE = "model.json"
# the packages whose versions can change what a run learns
VERSIONED = ("gymnasium", "numpy", "torch", "stable-baselines3", "sb3-contrib", "minari", "pybullet", "mujoco")


class RunFolderError(ValueError):
    """A run folder that cannot be used as asked (taken, missing, unreadable)."""


def _taken(folder: Path) -> bool:
    return folder.exists() and (not folder.is_dir() or any(folder.iterdir()))


def fresh_folder(folder: Path) -> Path:
    """`folder` when it is free (absent, or an empty folder), else the first free `folder-2`, `folder-3`..."""
    candidate, number = folder, 1
    while _taken(candidate):
        number += 1
        candidate = folder.with_name(f"{folder.name}-{number}")
    return candidate


def claim(folder: Path) -> bool:
    """Take `folder` for a new run; True when this call created it (so a failed start removes it again)."""
    try:
        folder.mkdir(parents=True)
        return True
    except FileExistsError:
        if _taken(folder):
            raise RunFolderError(
                f"{folder}: holds an earlier run, which is never overwritten; choose another "
                f"--out, or continue it with --resume {folder}"
            ) from None
        return False


def release(folder: Path, created: bool) -> None:
    """Undo `claim` after a start that failed: no half-made run is left behind."""
    if created:
        shutil.rmtree(folder, ignore_errors=True)
    elif folder.is_dir():  # an empty folder the user gave: empty it again, keep it
        for item in folder.iterdir():
            if item.is_dir():
                shutil.rmtree(item, ignore_errors=True)
            else:
                item.unlink(missing_ok=True)


def now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def versions() -> dict[str, str | None]:
    found: dict[str, str | None] = {"envfactory": __version__, "python": platform.python_version()}
    for name in VERSIONED:
        try:
            found[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            found[name] = None
    return found


@dataclass
class RunRecord:
    """model.json: the run's settings (written once) and its parts (one per start or resume)."""

    folder: Path
    data: dict

    @property
    def path(self) -> Path:
        return self.folder / RECORD_FILE

    @classmethod
    def read(cls, folder: Path) -> "RunRecord":
        path = folder / RECORD_FILE
        if not folder.is_dir():
            raise RunFolderError(f"{folder}: no such run folder")
        if not path.is_file():
            raise RunFolderError(f"{folder}: no {RECORD_FILE}, so not a run folder written by `envfactory train`")
        try:
            data = json.loads(path.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise RunFolderError(f"{path}: unreadable ({exc})") from None
        if not isinstance(data, dict) or not all(key in data for key in ("env_id", "algo", "seed", "parts")):
            raise RunFolderError(f"{path}: not a run record (env_id, algo, seed and parts expected)")
        return cls(folder, data)

    def save(self) -> None:
        # written whole, then renamed over the old one: a run killed mid-write keeps a readable record
        temporary = self.path.with_suffix(".json.tmp")
        temporary.write_text(json.dumps(self.data, indent=2, default=str))
        os.replace(temporary, self.path)

    @property
    def parts(self) -> list[dict]:
        return self.data["parts"]

    def begin_part(self, from_timesteps: int, target: int) -> None:
        self.parts.append(
            {
                "started": now(),
                "from_timesteps": from_timesteps,
                "target_timesteps": target,
                "status": "running",
                "versions": versions(),
            }
        )
        self.save()

    def progress(self, timesteps: int, trained_s: float) -> None:
        """What the saved model has done so far (written with every checkpoint)."""
        self.data["timesteps"] = int(timesteps)
        self.data["trained_s"] = round(float(trained_s), 1)
        if self.parts:  # a run stopped while it was still starting has no part yet
            self.parts[-1]["timesteps"] = int(timesteps)
        self.save()

    def end_part(self, status: str, error: str | None = None) -> None:
        part = self.parts[-1]
        part.update(status=status, ended=now())
        if error:
            part["error"] = error
        self.save()
