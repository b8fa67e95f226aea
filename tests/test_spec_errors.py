"""Every broken spec under broken_specs/ must fail with the message its first line expects."""

from pathlib import Path

import pytest

import envfactory
from envfactory.factory import register_specs

BROKEN = Path(__file__).parent / "broken_specs"
CASES = sorted(BROKEN.glob("*.yaml"))


def expected_message(path: Path) -> str:
    first = path.read_text().splitlines()[0]
    assert first.startswith("# expect: "), f"{path.name} must start with '# expect: <message>'"
    return first.removeprefix("# expect: ")


@pytest.mark.parametrize("path", CASES, ids=[p.stem for p in CASES])
def test_broken_spec_reports_file_line_and_path(path, tmp_path):
    (tmp_path / path.name).write_text(path.read_text())
    before = set(envfactory.records())
    added, problems = register_specs(tmp_path)
    assert added == [] and set(envfactory.records()) == before, "nothing from a broken spec is registered"
    assert len(problems) == 1
    assert expected_message(path) in str(problems[0]), str(problems[0])


def test_one_bad_spec_does_not_stop_the_good_ones(tmp_path):
    (tmp_path / "bad.yaml").write_text((BROKEN / "unknown_key.yaml").read_text())
    good = (BROKEN / "unknown_key.yaml").read_text().replace("tolerence", "tolerance").replace("BrokenKey", "GoodKey")
    (tmp_path / "good.yaml").write_text(good)
    added, problems = register_specs(tmp_path)
    assert added == ["GoodKey-v0"]
    assert len(problems) == 1 and "bad.yaml" in str(problems[0])
    import gymnasium as gym

    env = gym.make("GoodKey-v0")
    assert env.unwrapped.blueprint.spec.task.goal.tolerance == 0.02
    env.close()


def test_duplicate_id_names_both_files(tmp_path):
    text = (BROKEN / "unknown_key.yaml").read_text().replace("tolerence", "tolerance")
    text = text.replace("BrokenKey-v0", "UR5eReacherSim-v0")
    (tmp_path / "dup.yaml").write_text(text)
    added, problems = register_specs(tmp_path)
    assert added == []
    message = str(problems[0])
    assert "duplicate env ID 'UR5eReacherSim-v0'" in message and "ur5e_reach.yaml" in message and "dup.yaml" in message


def test_unknown_kwarg_lists_valid_ones():
    import gymnasium as gym

    with pytest.raises(envfactory.SpecError) as error:
        gym.make("UR5eReacherSim-v0", reward_typ="Sparse")
    assert "did you mean 'reward_type'" in str(error.value) and "delta_coeff" in str(error.value)


def test_bad_kwarg_value_names_the_kwarg():
    import gymnasium as gym

    with pytest.raises(envfactory.SpecError) as error:
        gym.make("UR5eReacherSim-v0", reward_type="Shaped")
    assert "gym.make kwarg reward_type='Shaped'" in str(error.value) and "env.reward_type" in str(error.value)


def test_bad_override_names_the_override():
    with pytest.raises(envfactory.SpecError) as error:
        envfactory.blueprint("UR5eReacherSim-v0", ["task.goal.tolerance=-1"])
    assert "override 'task.goal.tolerance=-1'" in str(error.value)
