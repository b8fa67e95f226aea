"""Compositions already made, kept on disk between processes.

Hydra's composition of a family (its YAML parsed by Hydra's pure-Python loader, the defaults merged) is about
half of a first gym.make in a fresh process, and it gives the same answer every time for the same files. So a
successful composition is stored under a key of everything it was made from: the family, the overrides, the
content of every YAML file its search roots offer, the code that composes, and Hydra's and OmegaConf's
versions. Any change to any of them is a different key, and the next process composes again.

Only compositions that succeeded are stored: an error is always found, and reported, by composing.
ENVFACTORY_CACHE_DIR moves the store (the tests give it a folder of their own); ENVFACTORY_CACHE_DIR=off
switches it off.
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import os
import pickle
from pathlib import Path

from envfactory.user_folders import cache_dir, store_in_cache

# the folders of a search root that Hydra's defaults lists reach into
GROUPS = ("robots", "tasks", "specs")
# the code whose output is stored
COMPOSING_CODE = ("compose.py", "sources.py", "composed_store.py")


def folder() -> Path | None:
    cache = cache_dir()
    return None if cache is None else cache / "composed"


def key(family_path: Path, search_roots: tuple[Path, ...], overrides: tuple[str, ...]) -> str:
    digest = hashlib.sha256()
    # the paths as given: a composition records the files it read by them, and a relative one means the working
    # folder's file (another process, elsewhere, must compose for itself)
    relative = not all(path.is_absolute() for path in (family_path, *search_roots))
    given = (str(family_path), [str(root) for root in search_roots], overrides, os.getcwd() if relative else "")
    digest.update(repr(given).encode())
    files = {family_path.resolve()}
    for root in (family_path.parent, *search_roots):
        for group in GROUPS:
            if (root / group).is_dir():
                files |= {path.resolve() for path in (root / group).rglob("*.yaml")}
        files |= {path.resolve() for path in root.glob("*.yaml")}
    for path in sorted(files):
        digest.update(str(path).encode())
        try:
            digest.update(path.read_bytes())
        except OSError:  # a file that is not there: composing will say so
            digest.update(b"\0missing")
    here = Path(__file__).parent
    for name in COMPOSING_CODE:
        digest.update((here / name).read_bytes())
    digest.update(repr([importlib.metadata.version(name) for name in ("hydra-core", "omegaconf")]).encode())
    return digest.hexdigest()[:32]


def load(entry: str):
    """The stored composition, or None; an unreadable entry counts as none (it is written again)."""
    where = folder()
    if where is None:
        return None
    try:
        with open(where / f"{entry}.pickle", "rb") as stored:
            return pickle.load(stored)
    except (OSError, pickle.UnpicklingError, EOFError, AttributeError, ImportError):
        return None


def save(entry: str, composed) -> None:
    """Stores it whole (written aside, then renamed into place); a store that cannot be written is skipped, as
    the composition is still correct without it."""
    where = folder()
    if where is not None:
        store_in_cache(
            where, f"{entry}.pickle", lambda path: path.write_bytes(pickle.dumps(composed, pickle.HIGHEST_PROTOCOL))
        )
