"""A user folder never breaks `import envfactory`; registration persists across processes."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from typer.testing import CliRunner

from envfactory.cli.app import app

BROKEN = Path(__file__).parent / "broken_specs"
GOOD = (BROKEN / "unknown_key.yaml").read_text().replace("tolerence", "tolerance")


def _python(code: str, **env) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env={**os.environ, **env}
    )


def _user_folder(tmp_path: Path) -> Path:
    folder = tmp_path / "user"
    folder.mkdir()
    (folder / "binary.yaml").write_bytes(bytes(range(256)) * 8)
    (folder / "space.yaml").write_text(GOOD.replace("BrokenKey-v0", "'My Reach-v0'"))
    (folder / "emoji.yaml").write_text(GOOD.replace("BrokenKey-v0", "'Reach\U0001f916-v0'"))
    (folder / "builtin.yaml").write_text(GOOD.replace("BrokenKey-v0", "UR5eReacherSim-v0"))
    (folder / "a_first.yaml").write_text(GOOD.replace("BrokenKey-v0", "Twice-v0"))
    (folder / "b_second.yaml").write_text(GOOD.replace("BrokenKey-v0", "Twice-v0"))
    (folder / "huge.yaml").write_text(GOOD + "#" + "x" * 300_000 + "\n")
    (folder / "fine.yaml").write_text(GOOD.replace("BrokenKey-v0", "UserFine-v0"))
    return folder


def test_broken_user_folder_never_breaks_the_import(tmp_path):
    folder = _user_folder(tmp_path)
    result = _python(
        "import gymnasium as gym, envfactory\n"
        "env = gym.make('UR5eReacherSim-v0'); env.reset(seed=0); env.close()\n"
        "env = gym.make('UserFine-v0'); env.reset(seed=0); env.close()\n"
        "env = gym.make('Twice-v0'); env.close()\n"
        "print('records', sorted(i for i, r in envfactory.records().items() if r.source != 'built-in'))",
        ENVFACTORY_SPEC_PATH=str(folder),
    )
    assert result.returncode == 0, result.stderr
    assert "records ['Twice-v0', 'UserFine-v0']" in result.stdout
    warnings = [line for line in result.stderr.splitlines() if line.startswith("envfactory:")]
    skipped = {Path(line.split("skipped: ")[1].split(":")[0]).name: line for line in warnings}
    # one line per bad file, naming the file (and line) and the reason
    assert set(skipped) == {"binary.yaml", "space.yaml", "emoji.yaml", "builtin.yaml", "b_second.yaml", "huge.yaml"}
    assert "not a text (UTF-8) file" in skipped["binary.yaml"]
    assert "space.yaml:13:" in skipped["space.yaml"] and "not a valid gymnasium ID" in skipped["space.yaml"]
    assert "not a valid gymnasium ID" in skipped["emoji.yaml"]
    assert "b_second.yaml:13:" in skipped["b_second.yaml"] and "a_first.yaml:13" in skipped["b_second.yaml"]
    assert "ur5e_reach.yaml:" in skipped["builtin.yaml"]
    assert "at most 256 KiB" in skipped["huge.yaml"]
    assert len(warnings) == 6


def test_register_persists_for_later_processes(tmp_path, monkeypatch):
    config = tmp_path / "config"
    monkeypatch.setenv("ENVFACTORY_CONFIG_DIR", str(config))
    folder = tmp_path / "mine"
    folder.mkdir()
    (folder / "mine.yaml").write_text(GOOD.replace("BrokenKey-v0", "Persisted-v0"))
    runner = CliRunner()
    result = runner.invoke(app, ["register", str(folder)])
    assert result.exit_code == 0, result.output
    assert "Persisted-v0: reset and step ok" in result.output
    assert str(folder.resolve()) in (config / "config.yaml").read_text()

    later = _python(
        "import gymnasium as gym, envfactory\n"
        "env = gym.make('Persisted-v0'); env.reset(seed=1); env.close(); print('made')",
        ENVFACTORY_CONFIG_DIR=str(config),
    )
    assert later.returncode == 0 and "made" in later.stdout, later.stderr
    sources = _python(
        "from envfactory.cli.app import app; app(['list', '--sources'])", ENVFACTORY_CONFIG_DIR=str(config)
    )
    assert "config" in sources.stdout and "Persisted-v0" in sources.stdout, sources.stdout + sources.stderr

    assert runner.invoke(app, ["unregister", str(folder)]).exit_code == 0
    gone = _python(
        "import gymnasium as gym, envfactory\nprint('Persisted-v0' in envfactory.records())",
        ENVFACTORY_CONFIG_DIR=str(config),
    )
    assert gone.stdout.strip() == "False", gone.stderr
    again = runner.invoke(app, ["unregister", str(folder)])
    assert again.exit_code == 1 and "is not recorded" in again.output


def test_broken_folder_is_not_recorded(tmp_path, monkeypatch):
    config = tmp_path / "config"
    monkeypatch.setenv("ENVFACTORY_CONFIG_DIR", str(config))
    folder = tmp_path / "bad"
    folder.mkdir()
    (folder / "bad.yaml").write_text((BROKEN / "goal_under_table.yaml").read_text())
    result = CliRunner().invoke(app, ["register", str(folder)])
    assert result.exit_code == 1 and "below the table top" in result.output
    assert not (config / "config.yaml").exists()


def test_corrupt_config_file_is_one_warning(tmp_path):
    config = tmp_path / "config"
    config.mkdir()
    (config / "config.yaml").write_text("spec_folders: {not: a list}\n")
    result = _python(
        "import envfactory; print(sorted({r.source for r in envfactory.records().values()}))",
        ENVFACTORY_CONFIG_DIR=str(config),
    )
    assert result.returncode == 0 and result.stdout.strip() == "['built-in']"  # the built-in IDs, nothing more
    assert "'spec_folders' must be a list" in result.stderr


def test_a_file_broken_below_its_registration_stays_out_whole_once_checked(tmp_path):
    """Import reads only the registration block; a family an earlier validate or make found
    broken is skipped whole (one warning line with the remembered file:line), until it changes."""
    config = tmp_path / "config"
    folder = tmp_path / "user"
    folder.mkdir()
    broken = folder / "broken.yaml"
    broken.write_text((BROKEN / "unknown_key.yaml").read_text().replace("BrokenKey-v0", "BelowBroken-v0"))
    (folder / "fine.yaml").write_text(GOOD.replace("BrokenKey-v0", "CheckedFine-v0"))
    env = {"ENVFACTORY_SPEC_PATH": str(folder), "ENVFACTORY_CONFIG_DIR": str(config)}
    probe = (
        "import gymnasium as gym, envfactory\n"
        "print('ids', sorted(i for i in ('BelowBroken-v0', 'CheckedFine-v0') if i in gym.registry))\n"
    )
    # never checked: registered lazily, as before (import composes nothing)
    assert "ids ['BelowBroken-v0', 'CheckedFine-v0']" in _python(probe, **env).stdout
    runner = CliRunner()
    result = runner.invoke(app, ["validate", str(folder)], env=env)
    assert result.exit_code == 1 and "tolerence" in result.output
    later = _python(probe, **env)
    assert "ids ['CheckedFine-v0']" in later.stdout, later.stdout + later.stderr
    warnings = [line for line in later.stderr.splitlines() if line.startswith("envfactory:")]
    assert len(warnings) == 1 and "broken.yaml:9: task.goal.tolerence: unknown key 'tolerence'" in warnings[0]
    # fixed: the remembered verdict no longer holds, the file registers again
    broken.write_text(broken.read_text().replace("tolerence", "tolerance"))
    assert "ids ['BelowBroken-v0', 'CheckedFine-v0']" in _python(probe, **env).stdout


def test_a_failed_make_keeps_the_family_out_of_later_imports(tmp_path):
    config = tmp_path / "config"
    folder = tmp_path / "user"
    folder.mkdir()
    (folder / "broken.yaml").write_text(
        (BROKEN / "unknown_key.yaml").read_text().replace("BrokenKey-v0", "MadeBroken-v0")
    )
    env = {"ENVFACTORY_SPEC_PATH": str(folder), "ENVFACTORY_CONFIG_DIR": str(config)}
    first = _python(
        "import gymnasium as gym, envfactory\n"
        "try:\n    gym.make('MadeBroken-v0')\nexcept envfactory.SpecError as exc:\n    print('refused')\n",
        **env,
    )
    assert "refused" in first.stdout, first.stderr
    later = _python("import gymnasium as gym, envfactory\nprint('MadeBroken-v0' in gym.registry)\n", **env)
    assert later.stdout.strip() == "False" and "unknown key 'tolerence'" in later.stderr
