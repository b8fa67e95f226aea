"""SimulationLimits ends an episode whose state no robot or object of the task can be in, and names why; the
common state passes. Judged on states written here, against the limits as the module states them."""

import dataclasses
import math

import gymnasium as gym
import numpy as np
import pytest

from envfactory.envs.sim_limits import OBJECT_SPEED_LIMIT, SCENE_HALF_HEIGHT, SimulationLeftLimits
from envfactory.geometry.obstacles import FLOOR_HALF_EXTENT


@pytest.fixture(scope="module")
def pushed():
    env = gym.make("VX300SPushSim-v0")
    env.reset(seed=0)
    yield env.unwrapped
    env.close()


def _with_cube(env, position=None, velocity=None):
    """The env's state with its cube moved (world frame) or set moving."""
    state = env._state
    cube = state.objects["cube"]
    changed = {}
    if position is not None:
        changed["position"] = env.sim_limits.frame.to_task(np.asarray(position, float))
    if velocity is not None:
        changed["linear_velocity"] = np.asarray(velocity, float)
    return dataclasses.replace(state, objects={"cube": dataclasses.replace(cube, **changed)})


def _reason(env, state) -> str:
    try:
        env.sim_limits.check(state)
    except SimulationLeftLimits as exc:
        return str(exc)
    return ""


def test_a_resting_cube_and_a_still_arm_pass(pushed):
    assert _reason(pushed, pushed._state) == ""


@pytest.mark.parametrize(
    "position",
    [
        [FLOOR_HALF_EXTENT + 0.01, 0.0, 0.1],
        [0.0, -FLOOR_HALF_EXTENT - 0.01, 0.1],
        [0.3, 0.0, -SCENE_HALF_HEIGHT - 0.01],
        [math.nan, 0.0, 0.1],
        [0.3, 0.0, math.inf],
    ],
)
def test_a_cube_off_the_floor_or_unreadable_is_out_of_the_scene(pushed, position):
    assert "object cube is at" in _reason(pushed, _with_cube(pushed, position=position))


def test_a_cube_just_inside_the_floor_stays(pushed):
    edge = FLOOR_HALF_EXTENT - 1e-6
    assert _reason(pushed, _with_cube(pushed, position=[edge, -edge, 0.1])) == ""


@pytest.mark.parametrize("velocity", [[OBJECT_SPEED_LIMIT * 0.8, OBJECT_SPEED_LIMIT * 0.7, 0.0], [0.0, math.nan, 0.0]])
def test_a_thrown_or_unreadable_cube_speed_ends_it(pushed, velocity):
    assert "thrown" in _reason(pushed, _with_cube(pushed, velocity=velocity))


def test_a_cube_below_the_speed_limit_stays(pushed):
    assert _reason(pushed, _with_cube(pushed, velocity=[OBJECT_SPEED_LIMIT * 0.7, OBJECT_SPEED_LIMIT * 0.7, 0])) == ""


def test_a_joint_read_past_the_speed_factor_or_nan_is_named(pushed):
    for reading in (pushed.sim_limits.speed_limit[0] * 1.01, math.nan):
        velocities = np.zeros_like(pushed._state.joint_velocities)
        velocities[0] = reading
        reason = _reason(pushed, dataclasses.replace(pushed._state, joint_velocities=velocities))
        assert f"joint {pushed.sim_limits.names[0]} reads" in reason
