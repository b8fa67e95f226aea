"""Builds the kernels ahead of time (native.py) at the argument types the envs call them with; where that cannot
be done (no C compiler), fills numba's cache with every entry point at those types and marks the cache ready for
serving.py. Started by serving.py in the background when neither form is there; one at a time per cache folder (a
second warm-up finds the lock taken and leaves). Run it by hand to prepare an install ahead of time:

    python -m envfactory.geometry.kernels.warmup [--native]
"""

from __future__ import annotations

import fcntl
import json
import os
import sys
import tempfile
import time
import traceback
from pathlib import Path

from numba.types import boolean, float64, int64

from envfactory.geometry.kernels import native, serving

# C-contiguous arrays of 1 to 4 dimensions; tests/test_kernel_serving.py checks that every Sim ID, in joint and EE
# mode, calls the entry points with exactly these types (a new type would compile in the calling process)
F1, F2, F3, F4 = float64[::1], float64[:, ::1], float64[:, :, ::1], float64[:, :, :, ::1]
I1, B1 = int64[::1], boolean[::1]
TREE = (I1, F3, I1, F2, I1, F1)  # JointTable: parent, placement, kind, axis, coordinate, gain
SIGNATURES = {
    "joint_frames": [(F1, *TREE, F3)],
    "capsule_bounds": [(F3, I1, F3, F1, F3, F2, F1, I1, F2, F2, I1, I1, F1)],
    "shape_sphere_gaps": [(F3, I1, F3, F1, I1, F1, float64, F1)],
    "swept_box_gap": [(F3, I1, F4, int64, int64, int64, int64, F2, F2, int64, int64, F3)],
    "swept_box_gaps": [(F3, I1, F4, int64, int64, I1, I1, F2, F2, I1, I1, F3, F1)],
    "motion_proof": [
        (F1, F1, F1, float64, float64, F2, F1, boolean, F1, F1, float64, float64, int64, int64, *TREE)
        + (I1, F3, F3, F2, F1, F1, I1, F2, F2, I1, I1, F1, F1, F1, F1, B1)
    ],
    "capsule_motion_unproven": [
        (F1, F1, F1, I1, F1, F1, F1, F1, F1, int64, int64, *TREE) + (I1, F3, F3, F2, F1, F1, I1, F2, F2, I1, I1, B1)
    ],
    "motion_clear_of_spheres": [(F1, F1, F1, *TREE, I1, F3, I1, F1, F2, float64, F2, F1, F1, float64, int64)],
    "solve_ik": [(F1, F1, F1, float64, F1, F2, boolean, float64, int64, float64, float64, I1, *TREE, F2, F1)],
}


def build_native() -> Path:
    """Compiles every entry point at its SIGNATURES into native.py's module, and puts it in place whole (a process
    that looks meanwhile finds either nothing or the finished module). Raises what numba.pycc raises, such as a
    missing C compiler, or an ImportError from a numba without pycc."""
    from numba.pycc import CC

    target = native.module_path()
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=target.parent) as scratch:
        compiler = CC(native.MODULE)
        compiler.output_dir = scratch
        for name, dispatcher in serving.compiled_kernels().items():
            for signature in SIGNATURES[name]:
                compiler.export(name, signature)(dispatcher.py_func)
        compiler.compile()
        os.replace(Path(scratch) / target.name, target)
    return target


def main(native_only: bool = False) -> int:
    """With `native_only` (ENVFACTORY_KERNELS=native): wait for a warm-up already running, then build the native
    module even where numba's cache is ready, and never fall back to that cache."""
    folder = serving.cache_folder()
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / serving.LOCK_FILE, "w") as lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX if native_only else fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            print("another warm-up holds the lock: leaving it to finish", flush=True)
            return 0
        if native.load() is not None or (serving.cache_is_ready(folder) and not native_only):
            return 0
        started = time.perf_counter()
        if native_only or not native.failed():
            print(f"building the safety kernels ahead of time into {native.module_path()}", flush=True)
            try:
                build_native()
                print(f"ready after {time.perf_counter() - started:.1f} s", flush=True)
                return 0
            except Exception:
                # most often no C compiler: numba's own form serves instead, compiled into its cache below
                failure = traceback.format_exc()
                native.mark_failed(failure)
                print(failure, flush=True)
                if native_only:
                    return 1
        print(f"compiling the safety kernels into {folder}", flush=True)
        try:
            for name, dispatcher in serving.compiled_kernels().items():
                for signature in SIGNATURES[name]:
                    dispatcher.compile(signature)
                print(f"  {name}: {time.perf_counter() - started:.1f} s", flush=True)
        except Exception:
            failure = traceback.format_exc()
            (folder / serving.FAILED_FILE).write_text(json.dumps(serving.source_stamp()) + "\n" + failure)
            print(failure, flush=True)
            return 1
        (folder / serving.FAILED_FILE).unlink(missing_ok=True)
        (folder / serving.READY_FILE).write_text(json.dumps(serving.source_stamp()))
        print(f"ready after {time.perf_counter() - started:.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(native_only="--native" in sys.argv[1:]))
