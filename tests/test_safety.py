"""Property: no joint target the safety check accepts puts a link below the floor or into the table."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import envfactory
from envfactory.envs import RobotEnv


@pytest.fixture(scope="module", params=["UR5eReacherSim-v0", "VX300SReacherSim-v0"])
def env(request):
    environment = RobotEnv(envfactory.blueprint(request.param))
    yield environment
    environment.close()


def draw_motion(env, data):
    """A start pose anywhere in the joint bounds and a target up to 0.5 rad per joint away."""
    kin = env.kinematics
    now = np.array([data.draw(st.floats(lo, hi)) for lo, hi in zip(kin.arm_lower, kin.arm_upper)])
    step = np.array([data.draw(st.floats(-0.5, 0.5)) for _ in now])
    return now, np.clip(now + step, kin.arm_lower, kin.arm_upper)


@settings(max_examples=300, deadline=None)
@given(data=st.data())
def test_accepted_targets_keep_every_link_clear(env, data):
    kin, safety = env.kinematics, env.safety
    now, target = draw_motion(env, data)
    if not safety.pose_is_clear(now):
        return  # the check judges motions that start from a safe pose
    verdict = safety.check(now, target)
    if verdict.accepted:
        clearance = safety.link_clearance(target)
        assert clearance.min() >= safety.settings.surface_margin - 1e-9
        points = kin.checked_link_positions(target)
        assert np.all(points[:, 2] - kin.checked_radii >= safety.surfaces.floor_z)


@settings(max_examples=300, deadline=None)
@given(data=st.data())
def test_accepted_motions_keep_the_midpoint_clear(env, data):
    """The check may skip the midpoint when the end pose is high enough; the skip must never hide a dip."""
    safety = env.safety
    now, target = draw_motion(env, data)
    if not safety.pose_is_clear(now):
        return
    if safety.check(now, target).accepted:
        for fraction in (0.25, 0.5, 0.75):
            assert safety.link_clearance(now + fraction * (target - now)).min() >= safety.settings.surface_margin - 1e-9


def test_lever_arm_bounds_every_point_move(env):
    kin = env.kinematics
    rng = np.random.default_rng(1)
    for _ in range(200):
        q = rng.uniform(kin.arm_lower, kin.arm_upper)
        dq = rng.uniform(-0.05, 0.05, q.size)
        moved = np.linalg.norm(kin.checked_link_positions(q + dq) - kin.checked_link_positions(q), axis=1)
        assert moved.max() <= kin.lever_arm * np.abs(dq).sum() + 1e-12


def test_check_rejects_known_collision(env):
    kin, safety = env.kinematics, env.safety
    lowest = safety.surfaces.table_top_z
    # search for a pose whose EE dips below the table top, then confirm the verdict
    rng = np.random.default_rng(0)
    for _ in range(2000):
        q = rng.uniform(kin.arm_lower, kin.arm_upper)
        ee, _ = kin.ee_pose(q)
        inside = np.all(ee[:2] >= safety.surfaces.table_min_xy) and np.all(ee[:2] <= safety.surfaces.table_max_xy)
        if inside and ee[2] < lowest:
            assert not safety.pose_is_clear(q)
            return
    pytest.fail("no pose below the table top was found to test")


def test_max_joint_delta_rejects_large_jumps(env):
    home = env.home
    target = home.copy()
    target[0] += 0.6
    verdict = env.safety.check(home, target)
    assert not verdict.accepted and "max_joint_delta" in verdict.reason
