"""From install to the first episode: the README's main command in a fresh clone and a fresh venv, cold (empty
numba cache, nothing byte-compiled) and then warm.

Clones this repository's HEAD into a temporary folder, makes a venv there and runs `pip install -e .` (from the
package index; pip's own download cache may serve it), then times the main command three ways: cold, warm while
the background warm-up may still run, and warm once the warm-up is done (the kernels built ahead of time, or
numba's cache marked ready where no C compiler is). "first row" is when the first episode's row reached the
terminal. The runs have envfactory's cache folder to themselves (ENVFACTORY_CACHE_DIR in the temporary folder, empty
before the cold run), as a new user has.

    python -m devkit.bench.cold_start [--episodes 5] [--markdown [PATH]]
"""

from __future__ import annotations

import argparse
import subprocess
import tempfile
import time
from pathlib import Path

from devkit.processes import user_environment
from devkit.report import REPO, Report, add_markdown_option

# without importing envfactory here: serving.READY_FILE, and native.MODULE's file
READY_FILE, NATIVE_FILES = "envfactory-kernels.ready", "envfactory_kernels_native*.so"


def _warmed(clone: Path) -> str:
    """What the warm-up left in the clone: the native module, numba's cache marked ready, or nothing yet."""
    if list(clone.rglob(NATIVE_FILES)):
        return "the kernels built ahead of time"
    return "numba's cache marked ready" if list(clone.rglob(READY_FILE)) else ""


def _new_user(folder: Path) -> dict[str, str]:
    """A user's environment with envfactory's cache of its own, empty at first (the hull and composition stores),
    and no NUMBA_CACHE_DIR: the kernels go where a new user's do."""
    environment = {name: value for name, value in user_environment().items() if name != "NUMBA_CACHE_DIR"}
    return {**environment, "ENVFACTORY_CACHE_DIR": str(folder / "cache")}


def _timed_run(venv: Path, clone: Path, episodes: int, environment: dict[str, str]) -> tuple[float, float, str]:
    """Seconds to the first episode row and to the end, and what the command said on stderr."""
    command = [str(venv / "bin" / "envfactory"), "run", "UR5eReacherSim-v0", "--episodes", str(episodes)]
    started = time.perf_counter()
    process = subprocess.Popen(
        [*command, "--policy", "scripted"],
        cwd=clone,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=environment,
    )
    first_row = None
    for line in process.stdout:
        if first_row is None and line.startswith("│ 0 "):
            first_row = time.perf_counter() - started
    stderr = process.stderr.read()
    if process.wait() != 0 or first_row is None:
        raise SystemExit(f"the main command failed:\n{stderr}")
    # the page names no folder of this machine: the clone is a temporary one
    return first_row, time.perf_counter() - started, stderr.replace(str(clone), "<clone>")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=5)
    parser.add_argument("--wait", type=float, default=600, help="longest wait for the warm-up, in seconds")
    add_markdown_option(parser)
    args = parser.parse_args()
    report = Report.start(parser, args, __doc__)
    with tempfile.TemporaryDirectory(prefix="envfactory-cold-") as folder:
        clone, venv = Path(folder) / "envfactory", Path(folder) / "venv"
        subprocess.run(["git", "clone", "-q", str(REPO), str(clone)], check=True)
        started = time.perf_counter()
        subprocess.run(["python3", "-m", "venv", str(venv)], check=True)
        pip = [str(venv / "bin" / "pip"), "install", "-q", "-e", "."]
        done = subprocess.run(pip, cwd=clone, capture_output=True, text=True, env=user_environment())
        if done.returncode != 0:
            raise SystemExit(f"pip install failed:\n{done.stderr}")
        installed = time.perf_counter() - started
        table = report.table(["run", "first episode row s", "whole command s", "said on stderr"])
        new_user = _new_user(Path(folder))
        cold_row, cold_total, said = _timed_run(venv, clone, args.episodes, new_user)
        table.add("cold: fresh venv, empty cache", f"{cold_row:.1f}", f"{cold_total:.1f}", said.strip() or "—")
        warming = time.perf_counter()
        row, total, said = _timed_run(venv, clone, args.episodes, new_user)
        table.add("second run, warm-up still running", f"{row:.1f}", f"{total:.1f}", said.strip() or "—")
        while not _warmed(clone):
            if time.perf_counter() - warming > args.wait:
                raise SystemExit(f"the warm-up did not finish within {args.wait:.0f} s")
            time.sleep(1)
        ready_after = time.perf_counter() - warming + cold_total
        row, total, said = _timed_run(venv, clone, args.episodes, new_user)
        table.add("warm: warm-up done", f"{row:.1f}", f"{total:.1f}", said.strip() or "—")
        warmed = _warmed(clone)
        log = next(clone.rglob("envfactory-kernels.log")).read_text().strip().splitlines()
    report.note(f"`pip install -e .` into the fresh venv took {installed:.0f} s.")
    report.note(
        f"The background warm-up left {warmed} about {ready_after:.0f} s after the cold command started; "
        f"its log ends: `{log[-1]}`."
    )
    report.finish()


if __name__ == "__main__":
    main()
