"""Sensing terms from the real path's timing: a Real ID run against the twin records each step's reading age
and command latency, and a latency the twin adds on purpose comes out as an action delay in whole steps."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from real_helpers import FAST, make_real
from typer.testing import CliRunner

from envfactory.cli.app import app
from envfactory.terms import SENSING
from envfactory.terms.sensing_from_log import sensing_terms, sensing_yaml


def test_measurements_become_terms_in_whole_steps():
    records = [
        {"joint_reading_age_s": age, "joint_reading_repeated": float(index % 10 == 0), "command_latency_s": latency}
        for index, (age, latency) in enumerate(zip([0.55, 0.6, 0.65] * 10, [1.1, math.nan, 0.9] * 10))
    ]
    terms, facts = sensing_terms(records, cycle_time=0.5)
    assert terms["late_observation"]["params"] == {"steps": 1}  # 0.6 s of a 0.5 s cycle
    assert terms["late_action"]["params"] == {"steps": 2}  # median of 1.1 and 0.9: 1.0 s
    assert terms["dropped_readings"]["params"]["probability"] == pytest.approx(0.1)
    for term in terms.values():  # what it prints is what the task's sensing accepts
        SENSING[term["term"]].params.model_validate(term["params"])
    assert any("20 commands" in fact for fact in facts)


def test_prompt_readings_give_delays_of_zero_steps():
    """What a robot YAML declares is what was measured, a delay that rounds to no step included."""
    records = [{"joint_reading_age_s": 0.01, "joint_reading_repeated": 0.0, "command_latency_s": 0.02}] * 5
    terms, facts = sensing_terms(records, cycle_time=0.5)
    assert terms == {
        "late_observation": {"term": "observation_delay", "params": {"steps": 0}},
        "late_action": {"term": "action_delay", "params": {"steps": 0}},
    }
    assert "  late_action: {term: action_delay, params: {steps: 0}}" in sensing_yaml(terms, facts, "log")


def test_a_twin_that_answers_late_gives_an_action_delay(twin, make, tmp_path):
    stand_in = twin(task="reach")
    stand_in.faults.delay_s = 0.25  # every message from the robot side arrives a quarter second late
    env = make_real(make, "UR5eReacherReal-v0", stand_in, max_episode_steps=20)
    env.reset(seed=0)
    log = tmp_path / "timing.jsonl"
    with log.open("w") as out:
        rng = np.random.default_rng(0)
        for _ in range(20):
            action = rng.uniform(env.action_space.low, env.action_space.high).astype(np.float32) * 0.5
            info = env.step(action)[4]
            assert info["timing"]["joint_reading_age_s"] >= 0.0
            out.write(json.dumps(info["timing"]) + "\n")
    latencies = [
        r["command_latency_s"]
        for r in map(json.loads, log.read_text().splitlines())
        if math.isfinite(r["command_latency_s"])
    ]
    # a command sent while the arm still moves from the one before may be credited with that motion and read
    # short, so the median is what counts: at least most of the added quarter second
    assert len(latencies) >= 5 and np.median(latencies) >= 0.2, latencies
    result = CliRunner().invoke(
        app, ["sensing-spec", str(log), "--id", "UR5eReacherReal-v0", "--cycle-time", str(FAST["action_cycle_time"])]
    )
    assert result.exit_code == 0, result.output
    # steps of 0.1 s (FAST): a quarter second is two or three
    steps = int(result.output.split("action_delay, params: {steps: ")[1].split("}")[0])
    assert steps >= 2 and FAST["action_cycle_time"] == 0.1


def test_a_sim_id_reports_no_timing(make):
    info = make("UR5eReacherSim-v0").reset(seed=0)[1]
    assert "timing" not in info


def test_a_timing_log_of_a_sim_id_is_refused(tmp_path):
    result = CliRunner().invoke(app, ["run", "UR5eReacherSim-v0", "-n", "1", "--timing-log", str(tmp_path / "t.jsonl")])
    assert result.exit_code != 0 and "use a Real ID" in result.output
    assert not (tmp_path / "t.jsonl").exists()


@pytest.mark.parametrize(
    "line, complaint",
    [
        ('{"joint_reading_age_s": NaN}', "joint_reading_age_s is nan, not a finite time"),
        ('{"joint_reading_age_s": "0.01"}', "joint_reading_age_s is '0.01', not a finite time"),
        ('{"joint_reading_age_s": 0.01, "joint_reading_repeated": 3}', "joint_reading_repeated is 3, not 0 or 1"),
        ('{"joint_reading_age_s": 0.01, "command_latency_s": "late"}', "command_latency_s is 'late', not a time"),
    ],
)
def test_a_log_with_readings_that_are_not_times_is_named_by_line(tmp_path, line, complaint):
    log = tmp_path / "timing.jsonl"
    log.write_text('{"joint_reading_age_s": 0.01, "command_latency_s": NaN}\n' + line + "\n")
    result = CliRunner().invoke(app, ["sensing-spec", str(log), "--id", "UR5eReacherReal-v0"])
    assert result.exit_code != 0 and (result.exception is None or isinstance(result.exception, SystemExit))
    assert f"{log}:2: {complaint}" in " ".join(result.output.split()), result.output
