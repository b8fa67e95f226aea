"""The step-parts benchmark times the env's real stages: each one a Push step runs is timed (a renamed stage
would fail here, not time nothing), and the physics inside the cycle is told apart."""

import pytest

from devkit.bench.step_parts import COLUMNS, run_one


@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_every_stage_of_a_push_step_is_timed(engine):
    result = run_one(f"VX300SPushSim-v0 [{engine}]", 40, 0, [])
    # a Push env has no fixtures: every other stage runs at every step
    ran = [column for column in COLUMNS if column not in ("fixture hold", "rest")]
    assert set(ran) <= set(result), sorted(set(ran) - set(result))
    assert all(result[column] > 0 for column in ran if column != "physics"), {c: result[c] for c in ran}
    assert result["physics"] >= 0 and "fixture hold" not in result
