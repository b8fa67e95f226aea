"""The generated docs pages (devkit/docs/generate.py) cannot drift from the code and the specs, and the
benchmark pages say how their figures were made (devkit/report.py)."""

from __future__ import annotations

import argparse
import io
import subprocess
import sys
from pathlib import Path

import pytest
from rich.console import Console

from devkit.docs import generate, mdtext, reference_pages
from devkit.report import Report, add_markdown_option, changed_settings, read_run_facts
from envfactory import factory
from envfactory.views.describe import description_parts, render_description

REPO = Path(__file__).resolve().parents[1]


def test_generated_pages_are_up_to_date():
    """The Markdown pages equal what the generator writes now (pictures are not compared)."""
    done = subprocess.run(
        [sys.executable, "-m", "devkit.docs.generate", "--check"], capture_output=True, text=True, cwd=REPO, timeout=300
    )
    assert done.returncode == 0, done.stderr


def test_check_names_a_missing_a_drifted_and_a_stale_page(tmp_path):
    (tmp_path / "envs").mkdir()
    (tmp_path / "envs" / "same.md").write_text("same\n")
    (tmp_path / "envs" / "drifted.md").write_text("edited by hand\n")
    (tmp_path / "envs" / "removed_family.md").write_text(mdtext.BANNER + "\n\n# an old page\n")
    (tmp_path / "envs" / "hand_written.md").write_text("# not generated, never touched\n")
    generated = {"envs/same.md": "same\n", "envs/drifted.md": "generated\n", "envs/new.md": "new\n"}
    assert sorted(generate.out_of_date(generated, tmp_path)) == [
        "docs/envs/drifted.md: out of date",
        "docs/envs/new.md: missing",
        "docs/envs/removed_family.md: no longer generated (delete it)",
    ]
    generate.write(generated, tmp_path)
    assert generate.out_of_date(generated, tmp_path) == []
    assert (tmp_path / "envs" / "hand_written.md").exists() and not (tmp_path / "envs" / "removed_family.md").exists()


def test_family_page_tables_are_the_describe_tables():
    """Every row `envfactory describe` prints for an ID is a row of its family page, cell for cell."""
    compiled = factory.blueprint("UR5ePnPGoalSim-v0")
    out = io.StringIO()
    render_description(compiled, Console(file=out, width=400))
    printed = {tuple(line.split()) for line in out.getvalue().splitlines()}
    page = (REPO / "docs" / "envs" / "ur5e_pnp.md").read_text()
    for part in description_parts(compiled):
        if part.kind in ("action", "reward", "observation"):  # tables this ID shows on the page (not shared)
            for row in zip(*(column.cells for column in part.body.columns)):
                assert tuple(" ".join(row).split()) in printed
                assert "| " + " | ".join(mdtext.console_text(cell) or " " for cell in row) + " |" in page


def test_markdown_escapes_what_markdown_would_read_as_markup():
    assert mdtext.escape("a_b _c_ *d* [e](f) <g> |") == r"a_b \_c\_ \*d\* \[e\](f) &lt;g> \|"
    assert mdtext.console_text("[bold]UR5eReacherSim-v0[/] at [0.0, 0.1]") == r"UR5eReacherSim-v0 at \[0.0, 0.1\]"
    assert mdtext.prose("the `envfactory terms` [list]") == r"the `envfactory terms` \[list\]"


def test_kwargs_page_refuses_a_kwarg_without_meaning():
    with pytest.raises(ValueError, match="no meaning for brand_new_kwarg"):
        reference_pages._check_accepted(
            {**{name: {"x": []} for name in reference_pages.MEANINGS}, "brand_new_kwarg": {"env.new": []}}
        )
    with pytest.raises(ValueError, match="different spec paths"):
        reference_pages._check_accepted({"seed": {"env.seed": [], "env.other": []}})


def test_schema_field_doc_of_a_kwarg_path():
    assert reference_pages.field_doc("env.action.delta_coeff") == "float = 0.05 (<= 1.0, > 0)"
    assert reference_pages.field_doc("robot.ros.object_poses.cube.topic") == "str"


def test_benchmark_page_says_how_it_was_made(tmp_path):
    page = tmp_path / "bench.md"
    argv = ["--steps", "3", "--markdown", str(page)]
    parser = argparse.ArgumentParser()
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--ids", nargs="*", default=["A-v0", "B-v0"])
    add_markdown_option(parser)
    changed = changed_settings(parser, parser.parse_args(argv))
    assert changed == ["steps=3 (default 1000)"]
    report = Report(
        str(page),
        "What a bench measures: steps.\n\n    python -m devkit.bench.bench\n\nMore words.",
        [str(REPO / "devkit" / "bench" / "bench.py"), *argv],
        out=io.StringIO(),
        changed=changed,
    )
    table = report.table(["ID", "steps/s"], title="3 steps")
    table.add("UR5eReacherSim-v0", "512")
    with pytest.raises(ValueError, match="2 columns"):
        table.add("only one cell")
    report.note("pooled: 512")
    report.finish()
    text = page.read_text()
    assert "| UR5eReacherSim-v0 | 512 |" in text and "pooled: 512" in text and "More words." in text
    assert "python -m devkit.bench.bench\n" not in text  # the usage block gives way to the exact command
    facts = read_run_facts(page)
    assert facts["script"] == "bench.py" and facts["title"] == "bench.py: What a bench measures"
    assert facts["Command"] == f"`python -m devkit.bench.bench --steps 3 --markdown {page}`"
    assert facts["Settings"] == "changed from the defaults: steps=3 (default 1000)"
    assert "cores" in facts["Machine"] and facts["Git revision"] and facts["Date"].count("UTC") == 1
