"""Which form of the kernels answers a call: the module compiled ahead of time (native.py) where warmup.py could
build it, else numba's just-in-time machine code once its cache holds them, and until either is there the same
Python source run by the interpreter.

Compiling the kernels takes a minute or more (numba's type inference of the inlined proof), and a newcomer's first
command would sit silent for all of it. So a process that finds neither form ready starts one background warm-up
(warmup.py, deduplicated across processes by a file lock), and meanwhile calls the kernels' own Python functions,
with the kernel-to-kernel calls inside them rebound to each other rather than to numba's dispatchers. Same source,
same float64 arithmetic: the verdicts are the compiled ones (tests/test_kernel_serving.py holds them equal), at
about a hundredth of the speed. Once warmup.py is done, the next call switches the process to the compiled form
for good. A process served the native module never imports numba.

ENVFACTORY_KERNELS chooses otherwise: `native` builds the ahead-of-time module in the calling process if it must,
`compiled` compiles numba's form in the calling process if it must (what warmup.py runs where it cannot build the
module), `interpreted` never compiles.
"""

from __future__ import annotations

import importlib
import json
import os
import subprocess
import sys
import time
import types
from pathlib import Path

from envfactory.geometry.kernels import native

# the kernels called from outside the package; the rest are called only by these
ENTRY_POINTS = {
    "joint_frames": "joints",
    "capsule_bounds": "pose",
    "shape_sphere_gaps": "pose",
    "swept_box_gap": "finger_sweep",
    "swept_box_gaps": "finger_sweep",
    "motion_proof": "motion",
    "capsule_motion_unproven": "bisection",
    "motion_clear_of_spheres": "spheres",
    "solve_ik": "inverse_kinematics",
}
MODES = ("auto", "native", "compiled", "interpreted")
READY_FILE = "envfactory-kernels.ready"
FAILED_FILE = "envfactory-kernels.failed"
LOCK_FILE = "envfactory-kernels.lock"
LOG_FILE = "envfactory-kernels.log"
CHECK_EVERY_S = 1.0


def kernel_modules() -> list[types.ModuleType]:
    return [importlib.import_module(f"{__package__}.{name}") for name in native.KERNEL_MODULES]


def compiled_kernels() -> dict:
    """numba's dispatchers of the entry points (importing numba)."""
    return {
        name: getattr(importlib.import_module(f"{__package__}.{module}"), name) for name, module in ENTRY_POINTS.items()
    }


def interpreted_kernels() -> dict[str, types.FunctionType]:
    """The kernels' Python functions, each module's copied into a namespace of its own in which every dispatcher
    (its own and those imported from sibling modules) is replaced by its Python twin, so no call inside them
    reaches numba's compiler."""
    from numba.core.dispatcher import Dispatcher

    modules = kernel_modules()
    namespaces = {module.__name__: dict(vars(module)) for module in modules}
    twins: dict[int, types.FunctionType] = {}
    for module in modules:
        namespace = namespaces[module.__name__]
        for value in vars(module).values():
            if isinstance(value, Dispatcher) and value.py_func.__module__ == module.__name__:
                source = value.py_func
                twins[id(value)] = types.FunctionType(
                    source.__code__, namespace, source.__name__, source.__defaults__, source.__closure__
                )
    for namespace in namespaces.values():
        for name, value in namespace.items():
            if isinstance(value, Dispatcher):
                namespace[name] = twins[id(value)]
    return {name: twins[id(dispatcher)] for name, dispatcher in compiled_kernels().items()}


def cache_folder() -> Path:
    """Where numba keeps these kernels' cache (beside the source, or its user-wide folder when that is read-only)."""
    return Path(compiled_kernels()["motion_proof"]._cache._cache_path)


def source_stamp() -> dict[str, object]:
    """What the cache was built from: numba invalidates a kernel's entries when its file's time or size changes."""
    import numba

    stamp: dict[str, object] = {"numba": numba.__version__, "python": sys.version.split()[0]}
    for module in kernel_modules():
        info = os.stat(module.__file__)
        stamp[Path(module.__file__).name] = [info.st_mtime, info.st_size]
    return stamp


def cache_is_ready(folder: Path | None = None) -> bool:
    try:
        marked = json.loads(((folder or cache_folder()) / READY_FILE).read_text())
    except (OSError, ValueError):
        return False
    return marked == json.loads(json.dumps(source_stamp()))


def warmup_failed(folder: Path) -> bool:
    """Whether a warm-up of these very sources ended in an error (warmup.py writes the stamp and the traceback)."""
    try:
        stamp = (folder / FAILED_FILE).read_text().split("\n", 1)[0]
    except OSError:
        return False
    return stamp == json.dumps(source_stamp())


def start_warmup(folder: Path) -> Path:
    """Starts warmup.py in its own session, so it finishes the cache even if this process ends first."""
    folder.mkdir(parents=True, exist_ok=True)
    log = folder / LOG_FILE
    with open(log, "a") as out:
        subprocess.Popen(
            [sys.executable, "-m", f"{__package__}.warmup"],
            stdout=out,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            start_new_session=True,
            env={**os.environ, "ENVFACTORY_KERNELS": "compiled"},
        )
    return log


def jit_disabled() -> bool:
    """numba's NUMBA_DISABLE_JIT, read without importing numba unless it is imported already."""
    if "numba" in sys.modules:
        return bool(sys.modules["numba"].config.DISABLE_JIT)
    return os.environ.get("NUMBA_DISABLE_JIT", "0").strip() not in ("", "0")


class KernelServer:
    """`kernels.motion_proof(...)` and the other entry points, served in the form the mode and the cache allow.
    Attributes are set on first use; in the interim form each call checks the cache at most once a second."""

    def __init__(self) -> None:
        self.mode = os.environ.get("ENVFACTORY_KERNELS", "auto")
        if self.mode not in MODES:
            raise ValueError(f"ENVFACTORY_KERNELS={self.mode!r}: expected one of {', '.join(MODES)}")
        self.form = ""  # "compiled" or "interpreted" once chosen
        self._next_check = 0.0

    def __getattr__(self, name: str):
        if name not in ENTRY_POINTS:
            raise AttributeError(name)
        self._choose()
        return self.__dict__[name]

    def _choose(self) -> None:
        if jit_disabled():  # numba's own switch: its "kernels" are the Python functions already
            self._serve(compiled_kernels(), "interpreted")
            return
        if self.mode == "native":
            self._serve(native.load() or self._built_here(), "native")
            return
        found = native.load() if self.mode == "auto" else None
        if found:
            self._serve(found, "native")
            return
        if self.mode == "compiled" or (self.mode == "auto" and cache_is_ready()):
            self._serve(compiled_kernels(), "compiled")
            return
        twins = interpreted_kernels()
        if self.mode == "interpreted":
            self._serve(twins, "interpreted")
            return
        folder = cache_folder()
        log = start_warmup(folder)
        print(
            "envfactory: compiling the safety kernels in the background, once per install (a minute or two; "
            f"log: {log}). Until then the same kernels run interpreted: the same verdicts, slower steps.",
            file=sys.stderr,
            flush=True,
        )
        self._serve({name: self._interim(name, twin, folder) for name, twin in twins.items()}, "interpreted")

    @staticmethod
    def _built_here() -> dict:
        """The native module, built now by warmup.py (waiting for one already running) if it is not there."""
        print("envfactory: building the safety kernels ahead of time (a minute or two, once)", file=sys.stderr)
        subprocess.run(
            [sys.executable, "-m", f"{__package__}.warmup", "--native"],
            env={**os.environ, "ENVFACTORY_KERNELS": "compiled"},
            stdin=subprocess.DEVNULL,
            check=False,
        )
        found = native.load()
        if found is None:
            reason = (native.failed().strip().splitlines() or ["see the warm-up's output above"])[-1]
            raise RuntimeError(f"ENVFACTORY_KERNELS=native: the kernels could not be built ahead of time: {reason}")
        return found

    def _serve(self, functions: dict, form: str) -> None:
        self.__dict__.update(functions)
        self.form = form

    def _interim(self, name: str, twin, folder: Path):
        def call(*args):
            now = time.monotonic()
            if now >= self._next_check:
                self._next_check = now + CHECK_EVERY_S
                found = native.load()
                if found:
                    self._serve(found, "native")
                    return self.__dict__[name](*args)
                if cache_is_ready(folder):
                    self._serve(compiled_kernels(), "compiled")
                    return self.__dict__[name](*args)
                if warmup_failed(folder):
                    # compiling here raises the warm-up's error where the user sees it, rather than running
                    # interpreted for good without a word
                    print(
                        f"envfactory: the kernels' warm-up failed (see {folder / FAILED_FILE}); compiling "
                        "them in this process",
                        file=sys.stderr,
                        flush=True,
                    )
                    self._serve(compiled_kernels(), "compiled")
                    return self.__dict__[name](*args)
            return twin(*args)

        return call


kernels = KernelServer()
