"""The docs site builds without a warning, and the README stays a short entry point whose set-up commands
are the ones CI and the main job run."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
README_MAX_LINES = 200
# .ci/run runs this line; the README must show it character for character
TEST_COMMAND = "python3 -m venv .venv && .venv/bin/pip install -e '.[test]' && .venv/bin/python -m pytest -q"
MAIN_JOB_COMMAND = (
    "python3 -m venv .venv && .venv/bin/pip install -e . && .venv/bin/envfactory run "
    "UR5eReacherSim-v0 --episodes 5 --policy scripted"
)


def test_the_docs_site_builds_strictly(tmp_path):
    """`mkdocs build --strict`: a page missing from docs/, a broken link or anchor fails the build."""
    pytest.importorskip("mkdocs", reason="the [docs] extra is not installed: pip install -e '.[docs]'")
    pytest.importorskip("material", reason="the [docs] extra is not installed: pip install -e '.[docs]'")
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )  # asserted below, with its output
    assert result.returncode == 0, f"mkdocs build --strict failed:\n{result.stdout}\n{result.stderr}"
    assert (tmp_path / "site" / "index.html").is_file()


def test_the_readme_is_short():
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= README_MAX_LINES, f"README.md has {len(lines)} lines; move depth to docs/"


@pytest.mark.parametrize("command", [TEST_COMMAND, MAIN_JOB_COMMAND], ids=["test command", "main job"])
def test_the_readme_shows_the_set_up_command_exactly(command):
    lines = README.read_text(encoding="utf-8").splitlines()
    assert command in lines, f"README.md lost the line {command!r}"


def test_ci_runs_the_readme_test_command():
    """The README's test command is the one CI runs, so the two cannot drift apart unnoticed."""
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()
    assert TEST_COMMAND in ci


def _yaml_block_after(text: str, marker: str) -> str:
    """The first ```yaml block after `marker` in the README."""
    after = text[text.index(marker) :]
    start = after.index("```yaml\n") + len("```yaml\n")
    return after[start : after.index("```", start)]


def test_the_readmes_lift_example_validates_and_its_expert_lifts_the_cube(tmp_path):
    """The README's write-a-task example, copied out of the README as a reader would: it validates, and the
    pick-and-place expert succeeds on it (3 episodes; the README runs 10)."""
    text = README.read_text(encoding="utf-8")
    folder = tmp_path / "my_specs"
    (folder / "tasks").mkdir(parents=True)
    (folder / "specs").mkdir()
    (folder / "tasks" / "lift.yaml").write_text(_yaml_block_after(text, "`my_specs/tasks/lift.yaml`"))
    (folder / "specs" / "vx300s_lift.yaml").write_text(_yaml_block_after(text, "`my_specs/specs/vx300s_lift.yaml`"))
    cli = [sys.executable, "-c", "from envfactory.cli.app import app; app()"]
    validated = subprocess.run([*cli, "validate", str(folder)], capture_output=True, text=True, timeout=300)
    assert validated.returncode == 0, validated.stdout + validated.stderr
    ran = subprocess.run(
        [*cli, "run", "VX300SLiftSim-v0", "--specs", str(folder), "-n", "3"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert ran.returncode == 0, ran.stdout + ran.stderr
    assert "success rate: 100% over 3 episodes" in ran.stdout, ran.stdout
