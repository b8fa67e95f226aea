"""What whole-family validation found, remembered across processes, so that `import envfactory`
can register a user family all or nothing without composing it (composing and compiling one
family takes 0.2-0.5 s; import reads only the registration block).

A verdict is recorded whenever a family is checked whole (`envfactory validate`, `register`,
`register_specs`) and when `make` of one of its IDs, as registered, fails. It holds for as long
as nothing it could depend on changed: the signature covers every file under the family's
spec folder (path, size, modification time), the built-in robots, tasks and specs, and the
envfactory version. A family without a current verdict registers lazily, as before.

The verdicts live beside the user config (ENVFACTORY_CONFIG_DIR moves both).
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
from pathlib import Path

from envfactory.registration import user_config
from envfactory.schema.folders import builtin_root, folder_of
from envfactory.version import __version__

FILE_NAME = "verdicts.json"
# A folder with more files than this gets no signature: walking it at import would cost too
# much, so its families register lazily.
MAX_SIGNED_FILES = 5000
MAX_VERDICTS = 2000  # the oldest are forgotten beyond this


def _path() -> Path:
    return user_config.config_dir() / FILE_NAME


def _stats(folder: Path, budget: int) -> list[tuple[str, int, int]] | None:
    stats = []
    for root, dirs, files in os.walk(folder):
        dirs[:] = sorted(d for d in dirs if not d.startswith(".") and d != "__pycache__")
        for name in files:
            path = Path(root) / name
            try:
                stat = path.stat()
            except OSError:
                continue
            stats.append((str(path.relative_to(folder)), stat.st_size, stat.st_mtime_ns))
            if len(stats) > budget:
                return None
    return sorted(stats)


@functools.lru_cache(maxsize=1)
def _builtin_signature() -> str:
    root = builtin_root()
    stats = [(part, _stats(root / part, MAX_SIGNED_FILES)) for part in ("robots", "tasks", "specs")]
    return hashlib.sha1(json.dumps([__version__, stats]).encode()).hexdigest()


def folder_stats(folder: Path) -> list | None:
    """What a folder's signature is taken from: every file's (path, size, mtime); None if too many."""
    return _stats(Path(folder).resolve(), MAX_SIGNED_FILES)


def signature(family_path: Path, stats: list | None = None) -> str | None:
    """A digest of everything the family's validity could depend on; None if too costly to take.
    `stats`: the folder's, when the caller took them once for several families."""
    stats = stats if stats is not None else folder_stats(folder_of(family_path))
    if stats is None:
        return None
    return hashlib.sha1(json.dumps([str(family_path.resolve()), stats, _builtin_signature()]).encode()).hexdigest()


def read() -> dict:
    try:
        data = json.loads(_path().read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def recall(family_path: Path, known: dict | None = None, stats: list | None = None) -> tuple[bool, dict] | None:
    """(valid, first problem as a dict) remembered for this family as it is now, or None.
    `known`: the verdicts, when the caller read them once for several families."""
    entry = (read() if known is None else known).get(str(family_path.resolve()))
    if not isinstance(entry, dict):
        return None
    current = signature(family_path, stats)
    if current is None or entry.get("signature") != current:
        return None
    problem = entry.get("problem")
    return bool(entry.get("valid")), problem if isinstance(problem, dict) else {}


def remember(family_path: Path, valid: bool, problem: dict | None = None) -> None:
    """Record a verdict; a config folder that cannot be written only loses the memory. The built-in
    families need none: import never consults it for them."""
    if folder_of(family_path).resolve() == builtin_root().resolve():
        return
    current = signature(family_path)
    if current is None:
        return
    data = read()
    key = str(family_path.resolve())
    data.pop(key, None)
    data[key] = {"signature": current, "valid": valid, "problem": problem or {}}
    while len(data) > MAX_VERDICTS:
        data.pop(next(iter(data)))
    path = _path()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        temporary = path.with_name(f"{FILE_NAME}.{os.getpid()}.tmp")
        temporary.write_text(json.dumps(data))
        temporary.replace(path)  # atomic: readers see the old file or the new one
    except OSError:
        pass
