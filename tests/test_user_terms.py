"""A user's own terms: a module named in the spec's `terms:` list adds observation and reward terms."""

from __future__ import annotations

import textwrap
import uuid

import gymnasium as gym
import numpy as np
import pytest

from envfactory.factory import register_specs, unregister_folder
from envfactory.terms.library import REWARDS, reward_term

MODULE = '''
"""The EE height above the table, and a reward for matching the goal's height."""

import numpy as np
from pydantic import Field

from envfactory.terms.library import (Description, TermParams, constant_bounds, fixed, observation_term,
                                      reward_term)


class Above(TermParams):
    table_z: float = Field(description="table top z in the task frame")


@observation_term(name="{prefix}_ee_height", size=fixed(1), bounds=constant_bounds(-1.0, 2.0), params=Above,
                  unit="m", describe=lambda layout, params: Description("EE height above the table", "FK", "m"))
def ee_height(state, params):
    """The EE's height above the table top."""
    return state.ee_position[2] - params.table_z


@reward_term(name="{prefix}_level", description="1 while the EE is within 5 cm of the goal's height")
def level_with_goal(achieved, desired, info, params, tolerance):
    return (np.abs(achieved[..., 2] - desired[..., 2]) < 0.05).astype(float)
'''

SPEC = """
defaults:
  - /robots@robot: ur5e
  - /tasks@task: reach
  - /specs/_defaults@_here_
  - _self_
terms: [{module}]
task:
  observation:
    - ee_position
    - {prefix}_ee_height: {{table_z: 0.775}}
  reward:
    dense:
      level: {{term: {prefix}_level, weight: 0.5}}
  goal:
    tolerance: 0.02
    box: [[0.4, -0.3, 0.85], [0.8, 0.3, 1.1]]
workspace: {{min: [-0.30, -0.85, 0.55], max: [1.20, 0.85, 1.50]}}
registration:
  ids:
    {env_id}: {{backend: sim}}
"""


def _folder(tmp_path, module_name):
    prefix = f"t{uuid.uuid4().hex[:8]}"
    (tmp_path / "specs").mkdir()
    (tmp_path / f"{module_name}.py").write_text(MODULE.replace("{prefix}", prefix))
    env_id = f"{prefix.capitalize()}Reach-v0"
    (tmp_path / "specs" / "mine.yaml").write_text(
        textwrap.dedent(SPEC).format(module=module_name, prefix=prefix, env_id=env_id)
    )
    return env_id


def test_terms_from_a_module_beside_the_spec(tmp_path):
    module_name = f"user_terms_{uuid.uuid4().hex[:8]}"
    env_id = _folder(tmp_path, module_name)
    added, problems = register_specs(tmp_path)
    try:
        assert problems == [] and added == [env_id]
        env = gym.make(env_id)
        observation, _ = env.reset(seed=0)
        state = env.unwrapped.state
        assert observation.shape == (4,)
        assert observation[3] == pytest.approx(state.ee_position[2] - 0.775, abs=1e-6)
        goal = env.unwrapped.goal
        _, reward, _, _, info = env.step(np.zeros(6, dtype=np.float32))
        ee = env.unwrapped.state.ee_position
        distance = float(np.linalg.norm(ee - goal))
        level = float(abs(ee[2] - goal[2]) < 0.05)
        # the original suite's dense reach reward, plus the user's term at weight 0.5
        expected = (
            -2.0 * distance
            + 20.0 * (distance < 0.02)
            - 0.5
            - 2.0 * info["action_out_of_bounds"]
            - 5.0 * info["action_rejected"]
            - 2.0 * info["goal_sampling_failed"]
            + 0.5 * level
        )
        assert reward == pytest.approx(expected, abs=1e-6)
        env.close()
    finally:
        unregister_folder(tmp_path)


def test_a_module_that_cannot_be_imported_is_named_with_file_and_line(tmp_path):
    (tmp_path / "specs").mkdir()
    (tmp_path / "specs" / "mine.yaml").write_text(
        textwrap.dedent(SPEC).format(module="no_such_terms_module", prefix="x", env_id="NoTerms-v0")
    )
    added, problems = register_specs(tmp_path)
    assert added == []
    message = str(problems[0])
    assert "mine.yaml:7: terms.0: cannot import term module 'no_such_terms_module'" in message, message


def test_a_registered_term_reads_as_its_function():
    name = f"t{uuid.uuid4().hex[:8]}_flag"

    def flag(achieved, desired, info, params, tolerance):
        """1 while the flag is up."""
        return info["flag"]

    try:
        assert reward_term(name=name, description="the flag")(flag) is flag
        term = REWARDS[name]
        assert (term.__doc__, term.__name__, term.__wrapped__) == (flag.__doc__, "flag", flag)
    finally:
        REWARDS.pop(name, None)
