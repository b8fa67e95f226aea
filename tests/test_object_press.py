"""The arm may not press a cube that rests on the table with anything but its fingers.

Judged by PyBullet, not by the guard's own geometry: the robot's URDF and a cube at the
env's reading of its pose, in a second client, measured at the commanded end pose.
"""

from dataclasses import replace

import numpy as np
import pinocchio as pin
import pybullet as p
import pytest

import envfactory
from devkit.oracles.bullet_judge import judge_steps
from envfactory.envs import RobotEnv
from envfactory.geometry.object_press import ObjectPressGuard

# a band around the guard's threshold where PyBullet and coal may disagree by their shape padding
ENGINE_BAND = 0.002


def _bullet_scene(env, cube):
    spec = env.blueprint.spec
    client = p.connect(p.DIRECT)
    body = p.loadURDF(
        str(env.kinematics.urdf_path),
        basePosition=list(spec.robot.mount),
        baseOrientation=p.getQuaternionFromEuler(list(spec.robot.mount_rpy)),
        useFixedBase=True,
        physicsClientId=client,
    )
    half = spec.task.objects["cube"].size / 2
    world = env.task_frame.to_world(cube.position)
    quaternion = pin.Quaternion(env.task_frame.rotation @ cube.rotation).coeffs()  # x, y, z, w
    cube_body = p.createMultiBody(
        0,
        p.createCollisionShape(p.GEOM_BOX, halfExtents=[half] * 3, physicsClientId=client),
        basePosition=list(world),
        baseOrientation=list(quaternion),
        physicsClientId=client,
    )
    joints = {
        p.getJointInfo(body, j, physicsClientId=client)[1].decode(): j
        for j in range(p.getNumJoints(body, physicsClientId=client))
    }
    links = {p.getJointInfo(body, j, physicsClientId=client)[12].decode(): j for j in joints.values()}
    return client, body, cube_body, joints, links


@pytest.mark.parametrize("env_id", ["VX300SPnPSim-v0", "UR5ePnPSim-v0"])
def test_non_finger_links_are_kept_off_a_resting_cube(env_id):
    env = RobotEnv(envfactory.blueprint(env_id))
    env.reset(seed=0)
    state, robot = env.state, env.blueprint.spec.robot
    guard = env.object_guard
    assert isinstance(guard, ObjectPressGuard)
    cube = state.objects["cube"]
    client, body, cube_body, joints, links = _bullet_scene(env, cube)
    guarded_links = {guard.collision.shapes[i].link for i in guard.guarded}
    assert not guarded_links & set(robot.gripper.pads.links or [])  # the fingers may touch it
    down = pin.rpy.rpyToMatrix(*robot.top_down_rpy)
    rng = np.random.default_rng(0)
    hover = env.kinematics.solve_ik(state.q_arm, cube.position + [0, 0, 0.12], down, gripper=state.gripper)
    assert hover.success
    refused = accepted = 0
    try:
        for _ in range(60):
            target = cube.position + np.append(
                rng.uniform(-0.03, 0.03, 2), rng.uniform(-0.15, 0.10)
            )  # deep enough for the palm
            solution = env.kinematics.solve_ik(hover.q_arm, target, down, gripper=robot.gripper.open)
            if not solution.success:
                continue
            for name, value in zip((j.name for j in robot.arm_joints), solution.q_arm):
                p.resetJointState(body, joints[name], float(value), physicsClientId=client)
            for name, gain in {robot.gripper.joint: 1.0, **robot.gripper.mimic}.items():
                p.resetJointState(body, joints[name], gain * robot.gripper.open, physicsClientId=client)
            depth = min(
                [
                    point[8]
                    for link in guarded_links
                    for point in p.getClosestPoints(
                        body, cube_body, 0.05, linkIndexA=links[link], physicsClientId=client
                    )
                ]
                or [np.inf]
            )
            verdict = guard.check(hover.q_arm, solution.q_arm, robot.gripper.open, robot.gripper.open, state.objects)
            if depth < -(guard.CONTACT_TOLERANCE + ENGINE_BAND):
                assert not verdict.accepted, (target, depth)
                assert "would press the cube (resting on the table top)" in verdict.reason
                refused += 1
            elif depth > ENGINE_BAND:
                assert verdict.accepted, (target, depth, verdict.reason)
                accepted += 1
    finally:
        p.disconnect(client)
    assert refused >= 5 and accepted >= 5, (refused, accepted)  # both sides of the line were tried


def test_a_lifted_cube_is_not_guarded():
    env = RobotEnv(envfactory.blueprint("VX300SPnPSim-v0"))
    env.reset(seed=0)
    state, robot = env.state, env.blueprint.spec.robot
    cube = state.objects["cube"]
    open_ = robot.gripper.open
    down = pin.rpy.rpyToMatrix(*robot.top_down_rpy)
    # the fingers straddle the cube ever lower until the bar comes down on it
    for depth in np.arange(0.0, 0.08, 0.005):
        into = env.kinematics.solve_ik(state.q_arm, cube.position - [0, 0, depth], down, gripper=open_)
        if into.success and not env.object_guard.check(state.q_arm, into.q_arm, open_, open_, state.objects).accepted:
            break
    else:
        pytest.fail("no pose pressed the resting cube")
    # the same pose against the cube held 5 cm up, off the table: it moves with the gripper
    held = {"cube": replace(cube, position=cube.position + [0, 0, 0.05])}
    assert env.object_guard.check(state.q_arm, into.q_arm, open_, open_, held).accepted


@pytest.mark.slow
def test_the_squeezed_cube_case_stays_clear_of_the_table():
    """The case the 2,000-step oracle found: the same action held, the gripper bar driven onto the cube."""
    env = RobotEnv(envfactory.blueprint("VX300SPnPSim-v0", ee_action_type=True))
    result = judge_steps(env, "repeated", 1000, seed=7)
    assert result["violations"] == [], result["violations"]
