"""An action the action space contains is never flagged out of bounds: the space's float32 bounds may round
past the declared rows (the UR5e's 3.14 is 3.1400001 in float32; the Robotiq's closed 0.8 is 0.80000001),
and a saturated policy sits exactly there. Judged by gymnasium's own `Box.contains`, not by the adapter."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import envfactory  # noqa: F401  (registers the IDs)

# (ID, kwargs): joint rows absolute and delta, normalised, and a gripper row; one step from home keeps a delta
# target inside the joint range, so a flag could only come from the bounds themselves
CASES = [
    ("UR5eReacherSim-v0", {}),
    ("UR5eReacherSim-v0", {"delta_action": False}),
    ("UR5ePnPSim-v0", {}),
    ("UR5ePnPSim-v0", {"normalize_actions": True}),
    ("VX300SPushSim-v0", {"delta_action": False}),
    ("VX300SPnPSim-v0", {}),
]
_envs: dict = {}


def _env(case: int):
    if case not in _envs:
        env_id, kwargs = CASES[case]
        _envs[case] = gym.make(env_id, **kwargs)
    return _envs[case]


def _action(env, picks: list[int], fractions: list[float]) -> np.ndarray:
    """Each row on its low bound, on its high bound, or inside, as float32."""
    low, high = env.action_space.low, env.action_space.high
    inside = np.clip(low + np.array(fractions[: low.size], np.float32) * (high - low), low, high)  # rounding
    choice = np.array(picks[: low.size])
    return np.where(choice == 0, low, np.where(choice == 1, high, inside)).astype(np.float32)


@pytest.mark.parametrize("case", range(len(CASES)), ids=[f"{i}-{k}" for i, k in CASES])
@settings(max_examples=12, deadline=None)
@given(
    picks=st.lists(st.integers(0, 2), min_size=8, max_size=8),
    fractions=st.lists(st.floats(0.0, 1.0), min_size=8, max_size=8),
)
def test_an_action_on_the_bounds_is_not_flagged(case, picks, fractions):
    env = _env(case)
    env.reset(seed=0)
    action = _action(env, picks, fractions)
    assert env.action_space.contains(action)
    info = env.step(action)[4]
    assert info["action_out_of_bounds"] == 0.0, (CASES[case], action)


@pytest.mark.parametrize("case", range(len(CASES)), ids=[f"{i}-{k}" for i, k in CASES])
def test_an_action_just_past_a_bound_is_flagged(case):
    """The flag still works: one float32 step beyond the high bound of the last row."""
    env = _env(case)
    env.reset(seed=0)
    action = env.action_space.high.copy()
    action[-1] = np.nextafter(action[-1], np.float32(np.inf), dtype=np.float32)
    assert not env.action_space.contains(action)
    assert env.step(action)[4]["action_out_of_bounds"] == 1.0
