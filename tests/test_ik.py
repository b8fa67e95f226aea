"""EE-mode inverse kinematics holding the wrist's orientation, judged by PyBullet's forward kinematics.

Targets come from PyBullet too: the EE where PyBullet puts it at a nearby joint
configuration, so every target is reachable and none is computed by envfactory.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pybullet as p
import pytest

import envfactory
from envfactory.envs import RobotEnv


def _bullet_ee(env, q_arm) -> tuple[np.ndarray, np.ndarray]:
    """PyBullet's EE position (task frame, by hand: the standard mounts are not turned) and rotation."""
    backend, robot = env.backend, env.blueprint.spec.robot
    assert not any(robot.mount_rpy)
    backend._set_joint_state(np.asarray(q_arm, float), None)
    links = {
        p.getJointInfo(backend.body, j, physicsClientId=backend.client)[12].decode(): j
        for j in range(p.getNumJoints(backend.body, physicsClientId=backend.client))
    }
    state = p.getLinkState(
        backend.body, links[robot.ee_frame], computeForwardKinematics=1, physicsClientId=backend.client
    )
    position = np.asarray(state[4]) - (np.asarray(robot.mount) if robot.task_frame == "base" else 0.0)
    return position, np.array(p.getMatrixFromQuaternion(state[5])).reshape(3, 3)


def _turn(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.arccos(np.clip((np.trace(a.T @ b) - 1) / 2, -1.0, 1.0)))


@pytest.mark.parametrize("env_id", ["RX200ReacherSim-v0", "VX300SReacherSim-v0"])
def test_held_orientation_ik_lands_on_the_point_and_keeps_the_wrist(env_id):
    """On the point within a millimetre by PyBullet; the wrist turned no more than the position-only
    solution turns it, and much less in the median. The RX200 has five joints: it cannot hold every
    orientation, so its position comes first and the wrist gets what is left."""
    env = RobotEnv(envfactory.blueprint(env_id))
    try:
        env.reset(seed=0)
        kin, rng = env.kinematics, np.random.default_rng(3)
        held, free = [], []
        for _ in range(40):
            start = np.clip(env.home + rng.uniform(-0.4, 0.4, env.home.size), kin.arm_lower, kin.arm_upper)
            nearby = np.clip(start + rng.uniform(-0.08, 0.08, start.size), kin.arm_lower, kin.arm_upper)
            _, rotation = _bullet_ee(env, start)
            target, _ = _bullet_ee(env, nearby)
            solution = kin.solve_ik(start, target, target_rotation=rotation, max_iterations=40)
            assert solution.success, (start, target)
            reached, reached_rotation = _bullet_ee(env, solution.q_arm)
            assert np.linalg.norm(reached - target) < 1e-3
            position_only = kin.solve_ik(start, target, max_iterations=60)
            assert position_only.success
            held.append(_turn(reached_rotation, rotation))
            free.append(_turn(_bullet_ee(env, position_only.q_arm)[1], rotation))
        held, free = np.array(held), np.array(free)
        assert np.all(held <= free + 1e-3), (held, free)
        assert np.median(held) < 0.5 * np.median(free), (np.median(held), np.median(free))
    finally:
        env.close()


def test_a_point_out_of_reach_is_refused():
    env = RobotEnv(envfactory.blueprint("RX200ReacherSim-v0"))
    try:
        env.reset(seed=0)
        _, rotation = _bullet_ee(env, env.home)
        for target_rotation in (rotation, None):
            solution = env.kinematics.solve_ik(env.home, np.array([2.0, 0.0, 0.3]), target_rotation=target_rotation)
            assert not solution.success and solution.position_error > 1.0
    finally:
        env.close()


@pytest.mark.parametrize("rows, columns", [(3, 5), (3, 6), (6, 6), (6, 7), (2, 5)])
def test_compiled_damped_least_squares_matches_lapack(rows, columns):
    """The IK's compiled step and pseudo-inverse against numpy's LAPACK solve and inverse of the same damped
    normal equations, on random Jacobians from well to badly conditioned (a column scaled down to near zero)."""
    from envfactory.geometry.kernels.damped_least_squares import damped_pseudo_inverse, damped_step

    rng = np.random.default_rng(rows * 10 + columns)
    for trial in range(100):
        jacobian = rng.normal(size=(rows, columns))
        if trial % 2:
            jacobian[:, rng.integers(columns)] *= 1e-6  # a joint near a singular direction
        residual = rng.normal(size=rows)
        damping = 10.0 ** rng.uniform(-3, -1)
        gram = jacobian @ jacobian.T + damping**2 * np.eye(rows)
        expected = jacobian.T @ np.linalg.solve(gram, residual)
        assert np.allclose(damped_step(jacobian, residual, damping), expected, rtol=1e-8, atol=1e-10)
        assert np.allclose(
            damped_pseudo_inverse(jacobian, damping), jacobian.T @ np.linalg.inv(gram), rtol=1e-8, atol=1e-10
        )


# ---------------------------------------------------------------- the compiled solve against Pinocchio's


def _damped(rows, residual, damping):
    return rows.T @ np.linalg.solve(rows @ rows.T + damping**2 * np.eye(rows.shape[0]), residual)


def _pinocchio_ik(kin, q_start, target, rotation, gripper, weight=0.5, iterations=40, tolerance=5e-4, damping=1e-2):
    """Kinematics.solve_ik's documented rules on Pinocchio's FK, Jacobian and log3 and LAPACK's solve (the oracle
    of the compiled iteration, which shares none of them). Targets in the model's frame."""
    model, data = kin.model, kin.model.createData()
    lower, upper = kin.arm_lower, kin.arm_upper
    q_arm = np.clip(np.array(q_start, float), lower, upper)
    arm_v = [model.idx_vs[model.getJointId(j.name)] for j in kin.robot.arm_joints]
    error, last_turn, closest, stalled = np.inf, np.inf, np.inf, 0
    for _ in range(iterations):
        q = kin.full_q(q_arm, gripper).copy()
        pin.forwardKinematics(model, data, q)
        placement = pin.updateFramePlacement(model, data, kin.ee_frame)
        position_error = target - placement.translation
        error = np.linalg.norm(position_error)
        if error < closest - 1e-7:
            closest, stalled = error, 0
        else:
            stalled += 1
            if stalled >= 5:
                break
        jacobian = pin.computeFrameJacobian(model, data, q, kin.ee_frame, pin.LOCAL_WORLD_ALIGNED)[:, arm_v]
        if rotation is None:
            if error < tolerance:
                return q_arm, error
            step = _damped(jacobian[:3], position_error, damping)
        else:
            rotation_error = pin.log3(rotation @ placement.rotation.T)
            turn = np.linalg.norm(rotation_error)
            if error < tolerance and (turn * weight < 10 * tolerance or abs(last_turn - turn) < 1e-6):
                return q_arm, error
            last_turn = turn
            if len(q_arm) < 6:
                inverse = jacobian[:3].T @ np.linalg.inv(jacobian[:3] @ jacobian[:3].T + damping**2 * np.eye(3))
                first = inverse @ position_error
                null = np.eye(len(q_arm)) - inverse @ jacobian[:3]
                second = _damped(jacobian[3:] @ null, weight * rotation_error - jacobian[3:] @ first, damping)
                step = first + null @ second
            else:
                rows = np.vstack([jacobian[:3], weight * jacobian[3:]])
                step = _damped(rows, np.concatenate([position_error, weight * rotation_error]), damping)
        q_arm = np.clip(q_arm + np.clip(step, -0.3, 0.3), lower, upper)
    return q_arm, error


@pytest.mark.parametrize(
    "env_id", ["UR5eReacherSim-v0", "VX300SReacherSim-v0", "RX200ReacherSim-v0", "NED2ReacherSim-v0"]
)
def test_the_compiled_solve_takes_pinocchios_steps(env_id):
    """Held orientation and position alone, from random starts to targets near and far (some out of reach, some
    with the tool to turn to an orientation the arm may not hold there): the compiled solve lands where the
    Pinocchio iteration does, to rounding (measured: within 5e-12 rad on these four arms)."""
    env = RobotEnv(envfactory.blueprint(env_id))
    kin, home = env.kinematics, env.home
    env.close()
    data = kin.model.createData()
    rng = np.random.default_rng(11)
    outcomes = set()
    for trial in range(120):
        start = np.clip(home + rng.uniform(-0.6, 0.6, home.size), kin.arm_lower, kin.arm_upper)
        reach = 0.1 if trial % 3 else 0.6  # a third of the targets far, some of them out of reach
        goal_q = np.clip(start + rng.uniform(-reach, reach, start.size), kin.arm_lower, kin.arm_upper)
        gripper = float(rng.uniform(0.0, 0.02))
        pin.forwardKinematics(kin.model, data, kin.full_q(goal_q, gripper).copy())
        placement = pin.updateFramePlacement(kin.model, data, kin.ee_frame)
        target, rotation = placement.translation.copy(), placement.rotation.copy()
        if trial % 4 == 0:
            rotation = pin.exp3(rng.normal(size=3)) @ rotation
        oriented = trial % 2 == 0
        expected_q, expected_error = _pinocchio_ik(kin, start, target, rotation if oriented else None, gripper)
        solution = kin.solve_ik(
            start,
            kin.to_task(target),
            target_rotation=rotation if oriented else None,
            gripper=gripper,
            max_iterations=40,
        )
        assert np.allclose(solution.q_arm, expected_q, rtol=0, atol=1e-9), (trial, solution.q_arm, expected_q)
        assert solution.position_error == pytest.approx(expected_error, rel=1e-6, abs=1e-12)
        assert solution.success == (expected_error < 5e-4)
        outcomes.add(solution.success)
    assert outcomes == {True, False}  # both kinds of ending were compared


def test_the_compiled_rotation_log_is_pinocchios():
    """Random turns, turns of a few microradians, and turns within a few microradians of a half turn or on it
    (where the axis comes from the symmetric part): the compiled logarithm against pin.log3."""
    from envfactory.geometry.kernels.inverse_kinematics import rotation_log

    rng = np.random.default_rng(5)
    out = np.empty(3)
    for trial in range(600):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        angle = [rng.uniform(0, np.pi), rng.uniform(0, 1e-5), np.pi - rng.uniform(0, 1e-5), np.pi, np.pi - 1e-10][
            trial % 5
        ]
        rotation = pin.exp3(axis * angle)
        for log in (rotation_log, rotation_log.py_func):
            log(np.ascontiguousarray(rotation), out)
            expected = pin.log3(rotation)
            if angle > np.pi - 1e-3:  # a half turn about an axis is the same turn about its opposite
                assert np.allclose(out, expected, atol=1e-6) or np.allclose(out, -expected, atol=1e-6), (out, expected)
                assert np.linalg.norm(out) == pytest.approx(np.linalg.norm(expected), abs=1e-9)
            else:
                assert np.allclose(out, expected, rtol=1e-9, atol=1e-12), (angle, out, expected)
