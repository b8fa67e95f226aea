"""What the benchmarks share about the processes they measure: the environment they run in, a worker's result
handed back on its stdout, and a process's resident memory."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

RESULT = "RESULT "  # the line of a worker's stdout that holds its result, as JSON


def user_environment() -> dict[str, str]:
    """This process's environment as a user's processes have it: Python writes its bytecode (a shell that sets
    PYTHONDONTWRITEBYTECODE would have every measured import compile its source again)."""
    return {name: value for name, value in os.environ.items() if name != "PYTHONDONTWRITEBYTECODE"}


def emit(result: dict) -> None:
    """A worker's result, for `run_worker` in the process that started it."""
    print(RESULT + json.dumps(result), flush=True)


def run_worker(command: list[str], what: str) -> dict:
    """Run a worker process and return the result it emitted; its stderr's end, naming `what`, if it did not."""
    done = subprocess.run(command, capture_output=True, text=True, env=user_environment())
    for line in done.stdout.splitlines():
        if line.startswith(RESULT):
            return json.loads(line[len(RESULT) :])
    raise RuntimeError(f"{what} failed:\n{done.stderr[-3000:]}")


def rss_mb(pid: int | str = "self") -> float:
    """A process's resident memory now, MB (NaN once it is gone)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return float("nan")
    for line in status.splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")
