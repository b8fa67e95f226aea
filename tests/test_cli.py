from typer.testing import CliRunner

from envfactory.cli.main import app

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
    result = runner.invoke(app, ["run", "VX300SReacherSim-v0", "-n", "2", "--video", str(video)])
    assert result.exit_code == 0, result.output
    assert "success rate" in result.output and "Return" in result.output
    assert video.stat().st_size > 1000


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
    assert "no Sim ID pairs robot 'ur10' with task 'push'" in result.output


def test_run_real_id_without_the_gate_is_refused(monkeypatch):
    monkeypatch.delenv("ALLOW_REAL_ROBOT_MOTION", raising=False)
    result = runner.invoke(app, ["run", "VX300SReacherReal-v0", "-n", "1"])
    assert result.exit_code == 1
    assert "real-robot motion is not allowed" in result.output
