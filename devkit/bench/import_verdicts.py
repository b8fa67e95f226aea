"""What remembered verdicts cost `import envfactory`.

A user folder of 10 valid families and one broken below its registration block is
imported three ways, alternating, in fresh processes: without the folder, with it
but no verdicts (lazy registration, as before verdicts existed), and with the
verdicts `envfactory validate` records (the broken family stays out). Prints the
medians and the per-round ratio of the last two.

    python -m devkit.bench.import_verdicts [rounds] [--markdown [PATH]]
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from devkit.report import Report, add_markdown_option

ROOT = Path(__file__).resolve().parents[2]  # the repository
GOOD = (ROOT / "tests" / "broken_specs" / "unknown_key.yaml").read_text()
PROBE = (
    "import envfactory, gymnasium as gym; "
    "print(sum(i.startswith('BenchFam') for i in gym.registry), 'BenchBroken-v0' in gym.registry)"
)


def main(rounds: int, report: Report) -> None:
    work = Path(tempfile.mkdtemp(prefix="envfactory-import-bench-"))
    try:
        folder, empty, checked = work / "user", work / "no-verdicts", work / "verdicts"
        folder.mkdir()
        for i in range(10):
            (folder / f"fam{i}.yaml").write_text(
                GOOD.replace("BrokenKey-v0", f"BenchFam{i}-v0").replace("tolerence", "tolerance")
            )
        (folder / "broken.yaml").write_text(GOOD.replace("BrokenKey-v0", "BenchBroken-v0"))
        subprocess.run(
            [sys.executable, "-m", "envfactory.cli", "validate", str(folder)],
            env={**os.environ, "ENVFACTORY_CONFIG_DIR": str(checked)},
            capture_output=True,
        )
        ways = {
            "no user folder": {"ENVFACTORY_CONFIG_DIR": str(empty)},
            "user folder, no verdicts": {"ENVFACTORY_CONFIG_DIR": str(empty), "ENVFACTORY_SPEC_PATH": str(folder)},
            "user folder, verdicts": {"ENVFACTORY_CONFIG_DIR": str(checked), "ENVFACTORY_SPEC_PATH": str(folder)},
        }
        times: dict[str, list[float]] = {way: [] for way in ways}
        seen = {}
        for _ in range(rounds):
            for way, env in ways.items():
                start = time.perf_counter()
                out = subprocess.run(
                    [sys.executable, "-c", PROBE], env={**os.environ, **env}, capture_output=True, text=True, cwd=work
                )
                times[way].append(time.perf_counter() - start)
                seen[way] = out.stdout.strip()
        table = report.table(
            ["import", "median s", "min s", "registered (BenchFam IDs, broken one)"],
            title=f"{rounds} rounds, the three ways alternating, a fresh process each",
        )
        for way in ways:
            table.add(way, f"{statistics.median(times[way]):.3f}", f"{min(times[way]):.3f}", seen[way])
        ratios = [b / a for a, b in zip(times["user folder, no verdicts"], times["user folder, verdicts"])]
        report.note(f"verdicts / no verdicts, per round: median {statistics.median(ratios):.3f}")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("rounds", nargs="?", type=int, default=9)
    add_markdown_option(parser)
    args = parser.parse_args()
    report = Report.start(parser, args, __doc__)
    main(args.rounds, report)
    report.finish()
