"""benchmarks/index.md: the result pages under docs/benchmarks/, each written by a benchmark script with
`--markdown PATH` (devkit/report.py), and the scripts that have not written one yet."""

from __future__ import annotations

import ast
from pathlib import Path

from devkit.docs import mdtext as md
from devkit.report import read_run_facts

# devkit/bench/learning.py writes its own page (not through report.py): listed under this name
LEARNING = ("learning.py", "learning.md")


def script_summaries(benchmarks: Path) -> dict[str, tuple[str, bool]]:
    """Each benchmark script's name -> (the first paragraph of its docstring, whether it writes pages through
    report.py). Read with ast: importing a benchmark would load the physics."""
    scripts = {}
    for path in sorted(benchmarks.glob("*.py")):
        if path.stem == "__init__":
            continue
        tree = ast.parse(path.read_text())
        doc = " ".join((ast.get_docstring(tree) or "").split("\n\n")[0].split())
        reports = any(isinstance(node, ast.ImportFrom) and node.module == "devkit.report" for node in ast.walk(tree))
        scripts[path.name] = (doc, reports)
    return scripts


def index_page(pages: Path, benchmarks: Path) -> str:
    scripts = script_summaries(benchmarks)
    rows, covered = [], set()
    for page in sorted(p for p in pages.glob("*.md") if p.name != "index.md"):
        facts = read_run_facts(page)
        script = facts.get("script") or (LEARNING[0] if page.name == LEARNING[1] else "")
        covered.add(script)
        rows.append(
            (
                f"[{md.prose(facts.get('title', page.stem))}]({page.name})",
                md.code(f"devkit/bench/{script}") if script else "—",
                md.escape(facts.get("Settings", "—")),
                md.escape(facts.get("Date", "—")),
                md.escape(facts.get("Machine", "—")),
            )
        )
    intro = (
        "Every page here is written by a script in `devkit/bench/`: run with `--markdown docs/benchmarks/NAME.md` "
        "it writes its results table together with the exact command line, the date, the machine (cores, CPU "
        "model), the load and the git revision. *Settings* says where a run left the script's defaults (fewer "
        "episodes, steps or rounds keep a run short on a small shared machine): such figures, like those of a "
        "run on a loaded machine, are a sample of the measurement, not its full run. Run a script again to "
        "refresh its page, then `python -m devkit.docs.generate` to refresh this index."
    )
    table = md.grid(["Page", "Written by", "Settings", "Date", "Machine"], rows) if rows else "No page yet."
    blocks = [intro, table]
    missing = [
        f"- `python -m devkit.bench.{Path(name).stem} --markdown docs/benchmarks/{Path(name).stem}.md`: "
        f"{md.prose(scripts[name][0])}"
        for name, (_, reports) in scripts.items()
        if reports and name not in covered and name != LEARNING[0]
    ]
    if LEARNING[0] in scripts and LEARNING[0] not in covered:
        missing.append(f"- `devkit/bench/{LEARNING[0]}` writes {LEARNING[1]} here: {md.prose(scripts[LEARNING[0]][0])}")
    if missing:
        blocks += ["## Not run for a page yet", "\n".join(missing)]
    others = [name for name, (_, reports) in scripts.items() if not reports and name != LEARNING[0]]
    if others:
        blocks += [
            "## Scripts without a page",
            "These print a report that is no results table; run them to read it.\n\n"
            + "\n".join(f"- `devkit/bench/{name}`: {md.prose(scripts[name][0])}" for name in others),
        ]
    return md.page("Benchmarks", *blocks)
