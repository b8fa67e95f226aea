from pathlib import Path

import pytest
from typer.testing import CliRunner

from envfactory.cli.app import app

runner = CliRunner()


def test_list_shows_every_reacher():
    result = runner.invoke(app, ["list"])
    assert result.exit_code == 0
    for env_id in ("UR5eReacherSim-v0", "UR5eReacherGoalSim-v0", "VX300SReacherSim-v0", "VX300SReacherGoalSim-v0"):
        assert env_id in result.output


def test_describe_prints_the_seed_table():
    result = runner.invoke(app, ["describe", "UR5eReacherSim-v0"])
    assert result.exit_code == 0
    assert "Box(27,)" in result.output and "Euclidean distance EE → goal" in result.output
    assert "/ur5e/joint_states.position" in result.output and "shoulder_pan_joint" in result.output


def test_describe_unknown_id_fails():
    result = runner.invoke(app, ["describe", "UR5eReacherSimm-v0"])
    assert result.exit_code != 0


def test_validate_ok_and_broken(tmp_path):
    assert runner.invoke(app, ["validate"]).exit_code == 0
    from pathlib import Path

    broken = Path(__file__).parent / "broken_specs" / "unknown_key.yaml"
    result = runner.invoke(app, ["validate", str(broken)])
    assert result.exit_code == 1
    assert "unknown_key.yaml:9: task.goal.tolerence" in result.output


def test_run_prints_a_table_and_writes_video(tmp_path):
    video = tmp_path / "reach.mp4"
    result = runner.invoke(app, ["run", "VX300SReacherSim-v0", "-n", "2", "--video", str(video), "--stop-at-success"])
    assert result.exit_code == 0, result.output
    assert "success rate" in result.output and "Return" in result.output
    assert video.stat().st_size > 1000


def _episode_rows(output: str) -> list[list[str]]:
    """The cells of each episode row of `run`'s table."""
    rows = [
        [cell.strip() for cell in line.strip("│ ").split("│")] for line in output.splitlines() if line.startswith("│")
    ]
    return [row for row in rows if row and row[0].isdigit()]


def test_run_follows_the_env_end_unless_told_to_stop_at_success():
    """A Dense ID never terminates at the goal: by default an episode lasts to the time limit, as a learner
    sees it; --stop-at-success ends it at the first success. The table says which, and when the goal was
    first reached either way."""
    import gymnasium as gym

    limit = gym.spec("UR5eReacherSim-v0").max_episode_steps
    full = runner.invoke(app, ["run", "UR5eReacherSim-v0", "-n", "1"])
    assert full.exit_code == 0, full.output
    text = " ".join(full.output.split())
    assert "each episode until the env ends it" in text and "Episodes end where the env ends them" in text
    [row] = _episode_rows(full.output)
    length, success, first = int(row[3]), row[4], row[5]
    assert length == limit and success == "yes" and first.startswith("step ")
    reached = int(first.split()[1])
    assert 0 < reached < limit

    short = runner.invoke(app, ["run", "UR5eReacherSim-v0", "-n", "1", "--stop-at-success"])
    assert short.exit_code == 0, short.output
    assert "each episode until its first success" in " ".join(short.output.split())
    [row] = _episode_rows(short.output)
    assert int(row[3]) == reached and row[5] == f"step {reached}"  # same seed, same path, cut at the goal
    assert float(row[2]) < float(_episode_rows(full.output)[0][2])


def test_describe_real_id_prints_topics_and_gates():
    result = runner.invoke(app, ["describe", "UR5ePushGoalReal-v0", "-k", "cube_pose_topic=/tracker/cube"])
    assert result.exit_code == 0, result.output
    assert "/scaled_pos_joint_traj_controller/command" in result.output and "/tracker/cube" in result.output
    assert "motion closed" in result.output


def test_list_shows_real_ids():
    result = runner.invoke(app, ["list"])
    for env_id in ("UR5ePushReal-v0", "UR5ePnPGoalReal-v0", "VX300SReacherReal-v0", "VX300SPnPGoalReal-v0"):
        assert env_id in result.output


def test_twin_of_an_unknown_robot_fails_clearly():
    result = runner.invoke(app, ["twin", "ur10", "--port", "0"])
    assert result.exit_code == 1
    assert "no robot named 'ur10' (robots with a real path: ned2, rx200, ur5e, vx300s)" in result.output
    task = runner.invoke(app, ["twin", "ur5e", "--task", "wipe", "--port", "0"])
    assert task.exit_code == 1 and "no Sim ID pairs robot 'ur5e' with task 'wipe'" in task.output


def test_twin_help_lists_every_robot_with_a_real_path():
    from envfactory import factory
    from envfactory.registration import registry

    real = {
        factory.blueprint(env_id).spec.robot.name
        for env_id, record in registry.records().items()
        if record.backend == "rosbridge"
    }
    assert real == {"ur5e", "vx300s", "rx200", "ned2"}
    result = runner.invoke(app, ["twin", "--help"])
    assert result.exit_code == 0
    assert f"robots with a real path: {', '.join(sorted(real))}" in " ".join(result.output.replace("│", " ").split())


def test_run_real_id_without_the_gate_is_refused(monkeypatch):
    monkeypatch.delenv("ALLOW_REAL_ROBOT_MOTION", raising=False)
    result = runner.invoke(app, ["run", "VX300SReacherReal-v0", "-n", "1"])
    assert result.exit_code == 1
    assert "real-robot motion is not allowed" in result.output


def test_bad_input_never_prints_a_traceback(tmp_path):
    cases = [
        (["validate", str(tmp_path / "missing")], "no such file or folder"),
        (["describe", "UR5eReacherSim-v0", "-k", "delta_coeff=["], "not valid YAML"),
        (["describe", "UR5eReacherSim-v0", "-k", "delta_coeff=.nan"], "finite number"),
        (["describe", "UR5eReacherSim-v0", "task.goal=["], "composition failed"),
        (["run", "UR5eReacherSim-v0", "--policy", "clever"], "use 'scripted', 'random' or a model file (.zip)"),
        (["unregister", str(tmp_path)], "is not recorded"),
    ]
    for args, expected in cases:
        result = runner.invoke(app, args)
        assert result.exit_code == 1, (args, result.output)
        assert expected in result.output, (args, result.output)
        # an escaped exception would be an Exception; a clean exit is SystemExit (a BaseException)
        assert "Traceback" not in result.output and not isinstance(result.exception, Exception), (
            args,
            result.exception,
        )


def test_video_path_is_checked_before_any_episode(tmp_path):
    for path, expected in (
        (tmp_path / "no" / "dir" / "out.mp4", "does not exist"),
        (Path("/proc/out.mp4"), "cannot write here"),
        (tmp_path, "must end in one of"),
        (tmp_path / "out.txt", "must end in one of"),
    ):
        result = runner.invoke(app, ["run", "UR5eReacherSim-v0", "-n", "3", "--video", str(path)])
        assert result.exit_code == 1 and expected in result.output, result.output
        assert "success rate" not in result.output  # refused before the episodes ran


def test_unexpected_error_is_one_line_and_debug_shows_the_traceback(monkeypatch):
    from envfactory import factory

    def broken(*args, **kwargs):
        raise RuntimeError("boom")

    monkeypatch.setattr(factory, "blueprint", broken)
    result = runner.invoke(app, ["describe", "UR5eReacherSim-v0"])
    assert result.exit_code == 1 and "RuntimeError: boom (run with --debug" in result.output
    debug = runner.invoke(app, ["--debug", "describe", "UR5eReacherSim-v0"])
    assert isinstance(debug.exception, RuntimeError)


def test_describe_reflects_kwargs_and_overrides():
    on = runner.invoke(app, ["describe", "UR5ePnPSim-v0"]).output
    assert "Lift stage" in on and "multi_goal=True" in on
    for args in (
        ["-k", "multi_goal=false"],
        ["multi_goal=false"],
        ["task.goal.lift.enabled=false"],
        ["-o", "task.goal.lift.enabled=false"],  # the override spelling of run
        ["-k", "overrides=[task.goal.lift.enabled=false]"],  # the kwarg spelling, still taken
    ):
        off = runner.invoke(app, ["describe", "UR5ePnPSim-v0", *args])
        assert off.exit_code == 0, off.output
        assert "Lift stage" not in off.output and "multi_goal=False" in off.output, args
        assert "current goal" not in off.output
    coeff = runner.invoke(app, ["describe", "UR5eReacherSim-v0", "-k", "delta_coeff=0.03", "-k", "max_joint_delta=0.2"])
    assert (
        "delta × 0.03" in coeff.output and "max_joint_delta=0.2" in coeff.output and "delta_coeff=0.03" in coeff.output
    )


def test_run_takes_overrides_as_minus_o_and_as_a_kwarg_alike():
    def run(*args):
        return runner.invoke(app, ["run", "UR5ePnPSim-v0", "-n", "1", "--policy", "random", *args])

    for override, exit_code in (("task.goal.lift.enabled=false", 0), ("env.no_such_key=3", 1)):
        minus_o, as_kwarg = run("-o", override), run("-k", f"overrides=[{override}]")
        assert minus_o.exit_code == as_kwarg.exit_code == exit_code, (minus_o.output, as_kwarg.output)
        if minus_o.exit_code:  # the error names the override, whichever way it came
            assert f"override '{override}'" in as_kwarg.output and as_kwarg.output == minus_o.output
    wrong = run("-k", "overrides=7")
    assert wrong.exit_code == 1 and "-k overrides=7: write a list of KEY=VALUE overrides" in wrong.output


@pytest.mark.parametrize(
    "command",
    [
        ["run", "UR5eReacherSim-v0", "-n", "1"],
        ["describe", "UR5eReacherSim-v0"],
        ["evaluate", "UR5eReacherSim-v0", "-n", "1"],
        ["train", "UR5eReacherSim-v0", "--steps", "10"],
        ["collect", "UR5eReacherSim-v0", "-n", "1"],
        ["safety-view", "UR5eReacherSim-v0"],
    ],
    ids=lambda command: command[0],
)
def test_every_command_that_makes_an_env_takes_minus_o_and_names_a_bad_override(command, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # a train or collect that got as far as writing would write here
    result = runner.invoke(app, [*command, "-o", "env.no_such_key=3"])
    message = " ".join(result.output.split())
    assert result.exit_code == 1 and "override 'env.no_such_key=3'" in message, message
    assert "Traceback" not in message and list(tmp_path.iterdir()) == []


def test_minus_o_was_trains_run_folder_and_says_where_that_went():
    result = runner.invoke(app, ["train", "UR5eReacherSim-v0", "-o", "runs/mine"])
    message = " ".join(result.output.split())
    assert result.exit_code == 1 and "-o 'runs/mine': an override is KEY=VALUE" in message, message
    assert "a run folder or an output file is given with --out" in message


def test_validate_reports_a_user_id_that_clashes_with_a_builtin(tmp_path):
    broken = Path(__file__).parent / "broken_specs" / "duplicate_builtin_id.yaml"
    result = runner.invoke(app, ["validate", str(broken)])
    assert result.exit_code == 1
    assert "duplicate_builtin_id.yaml:13" in result.output and "ur5e_reach.yaml:" in result.output


def test_terms_lists_every_term_and_expert_with_params_size_and_unit():
    from envfactory.experts import EXPERTS
    from envfactory.terms import IMAGES, OBSERVATIONS, REWARDS, TERMINATIONS
    from envfactory.views import term_catalog as catalog

    result = runner.invoke(app, ["terms"])
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    for name in [*OBSERVATIONS, *REWARDS, *TERMINATIONS, *IMAGES, *EXPERTS]:
        assert any(f" {name} " in line for line in lines), name  # whole, never cut short
    rows = {row[0]: row for row in catalog.observation_rows()}
    assert rows["is_grasped"][1:3] == ("1", "0 or 1")
    assert "distance: float = 0.05 (> 0, <= 0.5)" in rows["is_grasped"][3]
    assert rows["joint_positions"][1:3] == ("one per joint_states entry", "rad or m per joint")
    experts = {row[0]: row for row in catalog.expert_rows()}
    assert "grip: float | None = None" in experts["pnp"][1]
