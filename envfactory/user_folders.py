"""The user's own folders for envfactory: its config (the spec folders `envfactory register` recorded) and its cache
(what it can always make again: compositions, the collision meshes' hulls; the native kernels where the package's
own folder is read-only).

Each is its variable's folder if set, else the platform's: on Linux $XDG_CONFIG_HOME or $XDG_CACHE_HOME
(defaults ~/.config, ~/.cache), on macOS ~/Library/Application Support or ~/Library/Caches, on Windows
%APPDATA% or %LOCALAPPDATA%; an `envfactory` folder in it. ENVFACTORY_CACHE_DIR=off keeps no cache: every user
of it asks `cache_dir()` and gets None.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path
from typing import Callable

CONFIG_DIR_VARIABLE = "ENVFACTORY_CONFIG_DIR"
CACHE_DIR_VARIABLE = "ENVFACTORY_CACHE_DIR"
CACHE_OFF = "off"
# the platform's folder of each kind: (Windows variable, its default under home, macOS folder under home,
# XDG variable, its default under home)
PLATFORM_FOLDERS = {
    "config": ("APPDATA", "AppData/Roaming", "Library/Application Support", "XDG_CONFIG_HOME", ".config"),
    "cache": ("LOCALAPPDATA", "AppData/Local", "Library/Caches", "XDG_CACHE_HOME", ".cache"),
}


def _user_folder(variable: str, kind: str) -> Path:
    override = os.environ.get(variable)
    if override:
        return Path(override).expanduser()
    windows, windows_default, mac, xdg, xdg_default = PLATFORM_FOLDERS[kind]
    if sys.platform == "win32":
        base = Path(os.environ.get(windows) or Path.home() / windows_default)
    elif sys.platform == "darwin":
        base = Path.home() / mac
    else:
        base = Path(os.environ.get(xdg) or Path.home() / xdg_default)
    return base / "envfactory"


def config_dir() -> Path:
    return _user_folder(CONFIG_DIR_VARIABLE, "config")


def cache_dir() -> Path | None:
    """The cache folder, or None when switched off (never a folder named "off")."""
    if os.environ.get(CACHE_DIR_VARIABLE) == CACHE_OFF:
        return None
    return _user_folder(CACHE_DIR_VARIABLE, "cache")


def store_in_cache(where: Path, name: str, write: Callable[[Path], None]) -> None:
    """Keep a cache entry: `write(path)` fills a file beside it, which is then renamed into place, so a reader in
    another process never meets half an entry. A folder that cannot be written is skipped: whatever a cache keeps
    can always be made again."""
    try:
        where.mkdir(parents=True, exist_ok=True)
        handle, part = tempfile.mkstemp(dir=where, suffix=".part")
        os.close(handle)
        try:
            write(Path(part))
            os.replace(part, where / name)
        finally:
            Path(part).unlink(missing_ok=True)  # gone once renamed; else the half-written file
    except OSError:
        pass
