"""What gym.make costs: the import, the first make of an ID in a process and the second, each ID in a fresh
process, `--runs` times.

The processes run as a user's do after the first: Python writes its bytecode (PYTHONDONTWRITEBYTECODE is dropped,
where a shell sets it, or every import would compile its source again) and one untimed make per ID first leaves
what a later process reads: the bytecode, the composition on disk and the built kernels.

    python -m devkit.bench.make_times [--runs 3] [--ids ID ...] [--engine pybullet|mujoco] [--markdown [PATH]]
"""

from __future__ import annotations

import argparse
import subprocess
import sys

from devkit.processes import user_environment
from devkit.report import Report, add_markdown_option

WORKER = """
import time
start = time.perf_counter()
import envfactory, gymnasium as gym
imported = time.perf_counter()
gym.make({env_id!r}{kwargs})
first = time.perf_counter()
gym.make({env_id!r}{kwargs})
second = time.perf_counter()
print(f"{{imported - start:.3f}} {{first - imported:.3f}} {{second - first:.3f}}")
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument(
        "--ids",
        nargs="*",
        default=["UR5eReacherSim-v0", "UR5ePnPSim-v0", "VX300SPnPSim-v0", "RX200PnPSim-v0", "NED2PnPSim-v0"],
    )
    parser.add_argument(
        "--engine", choices=["pybullet", "mujoco"], help="the simulator to make each ID on (default: the ID's own)"
    )
    add_markdown_option(parser)
    args = parser.parse_args()
    report = Report.start(parser, args, __doc__)
    engine = args.engine or "each ID's default"
    table = report.table(
        ["ID", "import s", "first make s", "second make s", "second ÷ first"],
        title=f"each ID in {args.runs} fresh process(es), one row each; engine: {engine}",
    )
    environment = user_environment()
    for env_id in args.ids:
        kwargs = f", engine={args.engine!r}" if args.engine else ""
        worker = [sys.executable, "-c", WORKER.format(env_id=env_id, kwargs=kwargs)]
        subprocess.run(worker, capture_output=True, text=True, check=True, env=environment)  # untimed: the first
        for _ in range(args.runs):
            done = subprocess.run(worker, capture_output=True, text=True, check=True, env=environment)
            imported, first, second = (float(v) for v in done.stdout.split()[-3:])
            table.add(env_id, f"{imported:.2f}", f"{first:.2f}", f"{second:.3f}", f"{second / first:.0%}")
    report.finish()


if __name__ == "__main__":
    main()
