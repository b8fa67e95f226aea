"""A benchmark's results: tables printed row by row as they are measured and, with `--markdown PATH`, written
as a Markdown page that says how they were made (the exact command line, the date, the machine, the git
revision), so the docs site's benchmark pages are the scripts' own output (docs/benchmarks/).

    report = Report.start(parser, args, __doc__)
    table = report.table(["ID", "steps/s"], title="random actions")
    table.add("UR5eReacherSim-v0", "512")     # printed at once
    report.note("pooled median: 41 µs")
    report.finish()                           # writes the page when --markdown named one

`--markdown` alone prints the tables as Markdown instead of aligned text (nothing is written).
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import shlex
import subprocess
import sys
import time
from datetime import datetime, timezone
from pathlib import Path
from typing import TextIO

REPO = Path(__file__).resolve().parents[1]
STDOUT = "-"  # --markdown with no path: Markdown on stdout
RUN_HEADINGS = ("Command", "Settings", "Date", "Machine", "Load average (1 min)", "Python", "Git revision")


def add_markdown_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--markdown",
        nargs="?",
        const=STDOUT,
        metavar="PATH",
        help="write the results as a Markdown page to PATH (with the command line, date, machine "
        "and git revision); without PATH, print the tables as Markdown",
    )


def _cell(value: object) -> str:
    return str(value).replace("|", "\\|").replace("\n", " ") or " "


class ResultsTable:
    """One table of results, printed a row at a time (aligned text or Markdown) and kept for the page."""

    def __init__(self, columns: list[str], title: str, as_markdown: bool, out: TextIO):
        self.columns, self.title, self.rows = list(columns), title, []
        self._as_markdown, self._out = as_markdown, out
        # text columns as wide as their headings (a longer cell pushes its row out, never gets cut)
        self._widths = [max(len(column), 8) for column in self.columns]
        if title:
            print(f"\n{title}" if as_markdown else title, file=out, flush=True)
        for line in self.markdown_lines()[:2] if as_markdown else [self._text(self.columns)]:
            print(line, file=out, flush=True)

    def add(self, *cells: object) -> None:
        if len(cells) != len(self.columns):
            raise ValueError(f"a row of {len(cells)} cells for the {len(self.columns)} columns {self.columns}")
        row = [str(cell) for cell in cells]
        self.rows.append(row)
        print(self.markdown_lines([row])[-1] if self._as_markdown else self._text(row), file=self._out, flush=True)

    def _text(self, cells: list[str]) -> str:
        first, *rest = cells
        aligned = [first.ljust(max(self._widths[0], 26))] + [c.rjust(w) for c, w in zip(rest, self._widths[1:])]
        return "  ".join(aligned)

    def markdown_lines(self, rows: list[list[str]] | None = None) -> list[str]:
        lines = ["| " + " | ".join(map(_cell, self.columns)) + " |", "|" + "---|" * len(self.columns)]
        return lines + ["| " + " | ".join(map(_cell, row)) + " |" for row in (self.rows if rows is None else rows)]


class Report:
    """The tables and notes of one run, and the facts of the run, for the page."""

    def __init__(
        self,
        markdown: str | None,
        doc: str,
        argv: list[str],
        out: TextIO = sys.stdout,
        changed: list[str] | None = None,
    ):
        self.page = None if markdown in (None, STDOUT) else Path(markdown)
        self._as_markdown, self._out = markdown == STDOUT, out
        self.doc, self.argv = doc.strip(), list(argv)
        self.changed = changed or []  # the settings that differ from the script's defaults
        self.blocks: list[ResultsTable | str] = []
        self._started, self._load = time.monotonic(), os.getloadavg()[0]
        self._date = datetime.now(timezone.utc)
        if self.page is not None and not self.page.parent.is_dir():
            raise SystemExit(f"--markdown {self.page}: the folder {self.page.parent} does not exist")

    @classmethod
    def start(cls, parser: argparse.ArgumentParser, args: argparse.Namespace, doc: str) -> "Report":
        """The report of this process's run: its command line, and its settings against the parser's defaults."""
        return cls(args.markdown, doc, sys.argv, changed=changed_settings(parser, args))

    def table(self, columns: list[str], title: str = "") -> ResultsTable:
        table = ResultsTable(columns, title, self._as_markdown, self._out)
        self.blocks.append(table)
        return table

    def note(self, text: str) -> None:
        """A line of results that is no table row (a pooled figure, the settings of a section)."""
        print(text, file=self._out, flush=True)
        self.blocks.append(text)

    def finish(self) -> None:
        if self.page is None:
            return
        self.page.write_text(self.markdown())
        print(f"wrote {self.page}", file=self._out, flush=True)

    # ------------------------------------------------------------ the page

    def command(self) -> str:
        """The command line that runs this again: a script of the repository's package as its module."""
        return shlex.join(["python", *invocation(self.argv[0]), *self.argv[1:]])

    def run_facts(self) -> list[tuple[str, str]]:
        took = time.monotonic() - self._started
        settings = (
            "the script's defaults" if not self.changed else "changed from the defaults: " + ", ".join(self.changed)
        )
        return list(
            zip(
                RUN_HEADINGS,
                [
                    f"`{self.command()}`",
                    settings,
                    f"{self._date:%Y-%m-%d %H:%M} UTC, {took / 60:.1f} min",
                    machine(),
                    f"{self._load:.2f} before, {os.getloadavg()[0]:.2f} after",
                    f"{platform.python_version()} ({platform.system()} {platform.release()})",
                    revision(),
                ],
            )
        )

    def markdown(self) -> str:
        script = Path(self.argv[0]).name
        prose = _prose(self.doc)
        # the heading: the first paragraph up to its first colon or full stop
        heading = re.split(r"[:.](?:\s|$)", prose, maxsplit=1)[0]
        lines = [
            f"<!-- written by devkit/bench/{script} ({' '.join(['python', *invocation(self.argv[0])])}): "
            "the Command row is this run's own, at its git revision -->",
            f"# {script}: {heading}",
            "",
            prose,
            "",
        ]
        lines += ["| Run | |", "|---|---|"] + [f"| {name} | {_cell(value)} |" for name, value in self.run_facts()]
        lines += ["", "## Results"]
        for block in self.blocks:
            lines.append("")
            if isinstance(block, ResultsTable):
                if block.title:
                    lines += [f"### {block.title}", ""]
                lines += block.markdown_lines()
            else:
                lines.append(block)
        return "\n".join(lines) + "\n"


def invocation(script: str) -> list[str]:
    """How to run a script: `-m package.module` for a module of the repository's own package, else its path."""
    path = Path(script).resolve()
    if path.is_relative_to(REPO / "devkit"):
        return ["-m", ".".join(path.relative_to(REPO).with_suffix("").parts)]
    return [str(path.relative_to(REPO) if path.is_relative_to(REPO) else path)]


def changed_settings(parser: argparse.ArgumentParser, args: argparse.Namespace) -> list[str]:
    """`episodes=1 (default 5)` for each setting this run changed (--markdown itself left out)."""
    changed = []
    for name, value in vars(args).items():
        default = parser.get_default(name)
        if name != "markdown" and value != default:
            changed.append(f"{name}={_setting(value)} (default {_setting(default)})")
    return changed


def _setting(value: object) -> str:
    return " ".join(map(str, value)) if isinstance(value, (list, tuple)) else str(value)


def _prose(doc: str) -> str:
    """The docstring's paragraphs without its usage lines (the command line above says how it ran)."""
    paragraphs = [p for p in doc.strip().split("\n\n") if p.strip()]
    kept = [p for p in paragraphs if not p.startswith("    ") and "python -m devkit" not in p.split("\n")[0]]
    return "\n\n".join(" ".join(line.strip() for line in p.splitlines()) for p in kept)


def machine() -> str:
    cores = os.cpu_count() or 0
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else cores
    model = platform.processor() or "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.partition(":")[2].strip()
                break
    except OSError:
        pass
    usable_text = "" if usable == cores else f" ({usable} usable by this process)"
    return f"{cores} cores{usable_text}, {model}"


def revision() -> str:
    """The commit the tree is at, and whether files tracked in it differ (read-only git commands)."""

    def git(*arguments: str) -> str:
        done = subprocess.run(
            ["git", "--no-optional-locks", "-C", str(REPO), *arguments], capture_output=True, text=True, check=True
        )
        return done.stdout.strip()

    try:
        commit = git("rev-parse", "--short", "HEAD")
        changed = git("status", "--porcelain", "--untracked-files=no")
    except (OSError, subprocess.CalledProcessError):
        return "unknown (no git checkout)"
    return f"{commit}, with uncommitted changes" if changed else commit


def read_run_facts(page: Path) -> dict[str, str]:
    """The script, title and run facts of a page this module wrote (of another page: its title, if any)."""
    facts = {}
    for line in page.read_text().splitlines():
        written_by = re.match(r"<!-- written by (?:benchmarks|devkit/bench)/(\S+\.py)", line)
        if written_by and "script" not in facts:
            facts["script"] = written_by.group(1)
        if line.startswith("# ") and "title" not in facts:
            facts["title"] = line[2:].strip()
        cells = [c.strip() for c in line.strip().strip("|").split(" | ")]
        if line.startswith("| ") and len(cells) == 2 and cells[0] in RUN_HEADINGS and cells[0] not in facts:
            facts[cells[0]] = cells[1].replace("\\|", "|")
    return facts
