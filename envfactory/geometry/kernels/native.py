"""The kernels compiled ahead of time into one extension module, which a process imports without numba.

numba's just-in-time form costs every process its compiler: importing numba and llvmlite, then on the first call
its typing registries and the cached machine code, about 120 MB and a second of the first make. The same
functions compiled ahead of time by numba.pycc (at the argument types warmup.py lists) are plain machine code in a
1 MB module that needs only numpy. warmup.py builds it once per install (build_native); building needs a C
compiler, and where there is none warmup.py fills numba's cache instead (serving.py then serves the just-in-time
form).

numba.pycc is pending deprecation in numba (since 0.57; present in the versions this project installs). A numba
without it fails the build like a missing compiler does, and the just-in-time form serves.

The module is kept per stamp of what it was built from: the kernels' source, Python, numpy and numba. A changed
kernel builds anew instead of loading stale code.
"""

from __future__ import annotations

import hashlib
import importlib.machinery
import importlib.metadata
import importlib.util
import os
import sys
import sysconfig
import tempfile
from pathlib import Path

import numpy as np

from envfactory.user_folders import cache_dir

MODULE = "envfactory_kernels_native"
KERNELS = Path(__file__).parent
# the modules of numba kernels (serving.py serves them); every file whose code the module holds is one of them or
# a module of the constants they read as globals
KERNEL_MODULES = (
    "joints",
    "pose",
    "finger_sweep",
    "motion",
    "bisection",
    "spheres",
    "damped_least_squares",
    "inverse_kinematics",
)
SOURCES = (*KERNEL_MODULES, "joint_table", "outcomes")
FAILED_FILE = "native-build.failed"


def stamp() -> str:
    """What the module is built from, as a short hash."""
    digest = hashlib.sha256()
    for name in SOURCES:
        digest.update((KERNELS / f"{name}.py").read_bytes())
    versions = (sys.version.split()[0], np.__version__, importlib.metadata.version("numba"))
    digest.update(repr(versions).encode())
    return digest.hexdigest()[:16]


def folder() -> Path:
    """Where the module is kept: under NUMBA_CACHE_DIR when set (as numba's own cache, so one variable moves
    both), else beside the kernels when that is writable, else the user's cache, else (the cache switched off)
    the system's temporary folder."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return Path(os.environ["NUMBA_CACHE_DIR"]) / "envfactory-native"
    beside = KERNELS / "__pycache__"
    if os.access(beside if beside.exists() else KERNELS, os.W_OK):
        return beside / "native"
    cache = cache_dir()
    return (Path(tempfile.gettempdir()) / "envfactory" if cache is None else cache) / "native"


def module_path() -> Path:
    return folder() / stamp() / f"{MODULE}{sysconfig.get_config_var('EXT_SUFFIX')}"


def load() -> dict | None:
    """The entry points of the module built from these very sources, or None if there is none."""
    path = module_path()
    if not path.exists():
        return None
    loader = importlib.machinery.ExtensionFileLoader(MODULE, str(path))
    spec = importlib.util.spec_from_file_location(MODULE, path, loader=loader)
    module = importlib.util.module_from_spec(spec)
    loader.exec_module(module)
    return {name: function for name, function in vars(module).items() if not name.startswith("_")}


def failed() -> str:
    """Why the last build from these very sources failed, or "" if none did."""
    try:
        marked, reason = (folder() / FAILED_FILE).read_text().split("\n", 1)
    except (OSError, ValueError):
        return ""
    return reason if marked == stamp() else ""


def mark_failed(reason: str) -> None:
    folder().mkdir(parents=True, exist_ok=True)
    (folder() / FAILED_FILE).write_text(f"{stamp()}\n{reason}")
