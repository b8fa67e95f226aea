"""What gym.make costs: the import, the first make of an ID in a process and the second, each ID in a fresh
process, `--runs` times.

The processes run as a user's do after the first: Python writes its bytecode (PYTHONDONTWRITEBYTECODE is dropped,
where a shell sets it, or every import would compile its source again) and one untimed make per ID first leaves
what a later process reads: the bytecode, the composition and the mesh hulls on disk and the built kernels. Each
ID is made on each engine asked for, a table per engine; the engine's own package is imported by the first make.

    python -m devkit.bench.make_times [--runs 3] [--ids ID ...] [--engines pybullet mujoco] [--markdown [PATH]]
"""

from __future__ import annotations

import argparse
import subprocess
import sys

from devkit.bench import SIM_IDS
from devkit.processes import user_environment
from devkit.report import Report, add_markdown_option

WORKER = """
import time
start = time.perf_counter()
import envfactory, gymnasium as gym
imported = time.perf_counter()
gym.make({env_id!r}, engine={engine!r})
first = time.perf_counter()
gym.make({env_id!r}, engine={engine!r})
second = time.perf_counter()
print(f"{{imported - start:.3f}} {{first - imported:.3f}} {{second - first:.3f}}")
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument(
        "--ids",
        nargs="*",
        default=SIM_IDS,
    )
    parser.add_argument(
        "--engines",
        nargs="+",
        choices=["pybullet", "mujoco"],
        default=["pybullet", "mujoco"],
        help="the simulators to make each ID on, a table each (the import of the engine's own package is part of "
        "the first make: envfactory imports it when the first env needs it)",
    )
    add_markdown_option(parser)
    args = parser.parse_args()
    report = Report.start(parser, args, __doc__)
    environment = user_environment()
    for engine in args.engines:
        table = report.table(
            ["ID", "import s", "first make s", "second make s", "second ÷ first"],
            title=f"{engine}: each ID in {args.runs} fresh process(es), one row each",
        )
        for env_id in args.ids:
            worker = [sys.executable, "-c", WORKER.format(env_id=env_id, engine=engine)]
            subprocess.run(worker, capture_output=True, text=True, check=True, env=environment)  # untimed: the first
            for _ in range(args.runs):
                done = subprocess.run(worker, capture_output=True, text=True, check=True, env=environment)
                imported, first, second = (float(v) for v in done.stdout.split()[-3:])
                table.add(env_id, f"{imported:.2f}", f"{first:.2f}", f"{second:.3f}", f"{second / first:.0%}")
    report.finish()


if __name__ == "__main__":
    main()
