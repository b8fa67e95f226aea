"""Every observation lies inside its declared space, without the clipping backstop, under random and
adversarial policies: box extremes, the arm driven down, one action repeated, and the scripted expert
interrupted by extreme actions (which knocks and flings the cube in Push and PnP)."""

import numpy as np
import pytest
from conftest import SIM_IDS, action_modes

from devkit.oracles.bullet_judge import POLICIES
from envfactory.experts import make_policy


class _InterruptedExpert:
    """The scripted expert, with one step in four replaced by a box-extreme action."""

    def __init__(self, env):
        self.expert = make_policy("scripted", env)

    def __call__(self, env, rng, observation):  # the same call as the bullet_oracle policies
        if rng.random() < 0.25:
            return POLICIES["extremes"]()(env, rng, 0)
        return self.expert(observation)


def _outside(space, value) -> list[str]:
    low, high = space.low, space.high
    return [
        f"[{i}] {value[i]:.5g} not in [{low[i]:.5g}, {high[i]:.5g}]"
        for i in np.flatnonzero((value < low) | (value > high))
    ]


def _check(env, observation, info, where):
    parts = observation.items() if isinstance(observation, dict) else [("observation", observation)]
    for key, value in parts:
        space = env.observation_space[key] if isinstance(observation, dict) else env.observation_space
        assert value.dtype == space.dtype and value.shape == space.shape, (where, key)
        bad = _outside(space, value)
        assert not bad, f"{where}: {key} leaves its declared space: {bad}"
    assert info["observation_clipped"] == [], f"{where}: the backstop had to clip {info['observation_clipped']}"


def drive(env, steps: int, seed: int = 0, episode_length: int = 25) -> int:
    """Run every policy for a share of `steps`, checking each observation; the number of steps run."""
    rng = np.random.default_rng(seed)
    names = [*POLICIES, "expert"]
    ran = 0
    for index, name in enumerate(names):
        share = steps // len(names)
        observation, info = env.reset(seed=seed + index)
        _check(env, observation, info, f"{name} reset")
        policy = _InterruptedExpert(env) if name == "expert" else POLICIES[name]()
        step = 0
        for _ in range(share):
            action = policy(env.unwrapped, rng, observation if name == "expert" else step)
            observation, _, terminated, truncated, info = env.step(action)
            ran += 1
            step += 1
            _check(env, observation, info, f"{name} step {step}")
            if terminated or truncated or step == episode_length:
                observation, info = env.reset()
                _check(env, observation, info, f"{name} reset")
                if name == "expert":
                    policy = _InterruptedExpert(env)
                step = 0
    return ran


@pytest.mark.parametrize("env_id", SIM_IDS)
def test_observations_stay_inside_the_declared_space(env_id, make):
    env = make(env_id)
    assert drive(env, steps=150) >= 145


@pytest.mark.slow
@pytest.mark.parametrize(
    "env_id, ee",
    [(env_id, ee) for env_id in SIM_IDS for ee in action_modes(env_id)],
    ids=lambda value: {False: "joint", True: "ee"}.get(value, value) if isinstance(value, bool) else value,
)
def test_observations_stay_inside_the_declared_space_10k(env_id, ee, make):
    env = make(env_id, ee_action_type=ee)
    assert drive(env, steps=10_000, seed=1) >= 9_995


def test_a_clipped_column_is_logged_once_and_flagged_at_every_step(monkeypatch, caplog):
    """The backstop names a clipped column in info at every step, and in the log once per env."""
    import gymnasium as gym

    env = gym.make("VX300SReacherSim-v0")
    observations = env.unwrapped.observations
    computed = observations.compute
    monkeypatch.setattr(observations, "compute", lambda state: (computed(state)[0], ["3 (ee_rpy[0])=9.9"]))
    with caplog.at_level("WARNING", logger="envfactory"):
        infos = [env.reset(seed=0)[1]] + [env.step(env.action_space.sample() * 0)[-1] for _ in range(3)]
    env.close()
    assert all(info["observation_clipped"] == ["3 (ee_rpy[0])=9.9"] for info in infos)
    logged = [record.getMessage() for record in caplog.records if "outside its declared bounds" in record.getMessage()]
    assert len(logged) == 1 and "ee_rpy[0]" in logged[0]


def test_each_clipped_column_is_logged_once_when_it_first_clips(monkeypatch, caplog):
    """Once per column, not once per env: a second column that clips later is logged when it does."""
    import gymnasium as gym

    env = gym.make("VX300SReacherSim-v0")
    observations = env.unwrapped.observations
    computed = observations.compute
    calls = []

    def clipping(state):
        calls.append(None)
        columns = ["3 (ee_rpy[0])=9.9"] + (["4 (ee_rpy[1])=-9.9"] if len(calls) > 2 else [])
        return computed(state)[0], columns

    monkeypatch.setattr(observations, "compute", clipping)
    with caplog.at_level("WARNING", logger="envfactory"):
        env.reset(seed=0)
        for _ in range(4):
            env.step(env.action_space.sample() * 0)
    env.close()
    logged = [record.getMessage() for record in caplog.records if "outside its declared bounds" in record.getMessage()]
    assert len(logged) == 2, logged
    assert "ee_rpy[0]" in logged[0] and "ee_rpy[1]" in logged[1] and "ee_rpy[0]" not in logged[1]
