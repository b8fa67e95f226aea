"""Slide: a low-friction puck struck to a goal beyond the arm's reach, judged by the physics of sliding."""

import gymnasium as gym
import mujoco
import numpy as np
import pybullet as p
import pytest

import envfactory
from envfactory.envs.episodes import run_episodes, success_rate
from envfactory.experts import make_policy
from envfactory.schema.errors import SpecError

SLIDE_IDS = ["PandaSlideSim-v0", "UR5eSlideSim-v0", "VX300SSlideSim-v0", "RX200SlideSim-v0"]
GRAVITY = 9.81


def _kick(env, speed: float) -> None:
    """Give the puck a speed along x directly in the engine, with no arm in contact."""
    backend = env.unwrapped.backend
    if env.unwrapped.blueprint.backend == "pybullet":
        p.resetBaseVelocity(backend.objects["puck"], [speed, 0, 0], [0, 0, 0], physicsClientId=backend.client)
    else:
        body = mujoco.mj_name2id(backend.model, mujoco.mjtObj.mjOBJ_BODY, "object:puck")
        backend.data.qvel[backend.model.jnt_dofadr[backend.model.body_jntadr[body]]] = speed


@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_a_kicked_puck_slides_as_coulomb_friction_says(engine):
    """The oracle is v^2 / (2 mu g), mu the product of the puck's and the table's friction (0.04 x 0.5): within
    6% at 0.2 and 0.4 m/s on both engines (a puck that tips, or a friction law the engine does not apply,
    misses it by far more)."""
    env = gym.make("VX300SSlideSim-v0", engine=engine)
    try:
        spec = env.unwrapped.blueprint.spec
        friction = spec.task.objects["puck"].friction * 0.5
        for speed in (0.2, 0.4):
            env.reset(seed=0)
            start = env.unwrapped.backend.read_object("puck").position.copy()
            _kick(env, speed)
            for _ in range(16):
                env.unwrapped.backend.advance(0.25)
            end = env.unwrapped.backend.read_object("puck").position
            expected = speed**2 / (2 * friction * GRAVITY)
            assert end[0] - start[0] == pytest.approx(expected, rel=0.06), (engine, speed)
            assert abs(end[1] - start[1]) < 0.01 and end[2] == pytest.approx(start[2], abs=2e-3)
    finally:
        env.close()


@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_a_puck_struck_off_the_table_lands_on_the_floor(engine):
    """Off the table's far edge the puck falls 0.78 m and must stop on the floor in both engines. MuJoCo's soft
    contact let it pass through the 2 cm floor box at that speed (it fell to -10 m): the floor is a plane there."""
    env = gym.make("VX300SSlideSim-v0", engine=engine)
    try:
        env.reset(seed=0)
        backend, table = env.unwrapped.backend, env.unwrapped.blueprint.spec.scene.table
        over_edge = [table.center[0] + table.size[0] / 2 + 0.1, 0.0, table.top_z + 0.05]
        if engine == "pybullet":
            body = backend.objects["puck"]
            p.resetBasePositionAndOrientation(body, over_edge, [0, 0, 0, 1], physicsClientId=backend.client)
            p.resetBaseVelocity(body, [0.3, 0, 0], [2.0, 1.0, 0], physicsClientId=backend.client)
        else:
            body = mujoco.mj_name2id(backend.model, mujoco.mjtObj.mjOBJ_BODY, "object:puck")
            joint = backend.model.body_jntadr[body]
            backend.data.qpos[backend.model.jnt_qposadr[joint] : backend.model.jnt_qposadr[joint] + 3] = over_edge
            backend.data.qvel[backend.model.jnt_dofadr[joint] : backend.model.jnt_dofadr[joint] + 6] = [
                0.3,
                0,
                0,
                2,
                1,
                0,
            ]
            mujoco.mj_forward(backend.model, backend.data)
        for _ in range(12):
            backend.advance(0.25)
        world_z = env.unwrapped.task_frame.to_world(backend.read_object("puck").position)[2]
        assert 0.0 < world_z < 0.04, (engine, world_z)  # resting on the floor at z 0, on its face or its side
    finally:
        env.close()


def _bullet_reaches(env, point_task, rpy_task) -> bool:
    """PyBullet's own IK and forward kinematics, not the check's Pinocchio model: whether the EE gets to within
    5 mm and 0.05 rad of the pose, from home."""
    unwrapped = env.unwrapped
    backend, frame = unwrapped.backend, unwrapped.task_frame
    body, client = backend.body, backend.client
    joints = [j for j in range(p.getNumJoints(body, physicsClientId=client))]
    links = {p.getJointInfo(body, j, physicsClientId=client)[12].decode(): j for j in joints}
    ee = links[unwrapped.blueprint.spec.robot.ee_frame]
    movable = [j for j in joints if p.getJointInfo(body, j, physicsClientId=client)[2] != p.JOINT_FIXED]
    target = frame.to_world(np.asarray(point_task, float))
    orientation = p.getQuaternionFromEuler(list(rpy_task))  # the task frames of these robots turn no axis
    solution = p.calculateInverseKinematics(
        body, ee, target, orientation, maxNumIterations=1000, residualThreshold=1e-7, physicsClientId=client
    )
    for joint, value in zip(movable, solution):
        p.resetJointState(body, joint, value, physicsClientId=client)
    position, quaternion = p.getLinkState(body, ee, computeForwardKinematics=True, physicsClientId=client)[4:6]
    turned = p.getDifferenceQuaternion(quaternion, orientation)
    angle = 2 * np.arccos(min(1.0, abs(turned[3])))
    return np.linalg.norm(np.subtract(position, target)) < 0.005 and angle < 0.05


def test_the_goal_lies_beyond_the_arms_reach():
    """What makes it Slide: at the goal box's far corners the arm cannot hold its gripper down at the height it
    strikes from, by PyBullet's own IK, so the puck must travel there on its own."""
    for env_id in SLIDE_IDS:
        spec = envfactory.blueprint(env_id).spec
        assert spec.task.goal.within_reach is False
        env = gym.make(env_id)
        try:
            low, high = (np.asarray(b, float) for b in spec.task.goal.box)
            height = low[2] + spec.task.expert.params["height"]
            # the same query succeeds over the puck's spawn, where the arm does strike from
            spawn = np.asarray(spec.task.objects["puck"].spawn.position, float) + [0, 0, height - low[2]]
            env.reset(seed=0)
            assert _bullet_reaches(env, spawn, spec.robot.top_down_rpy), env_id
            for y in (low[1], high[1]):
                env.reset(seed=0)
                assert not _bullet_reaches(env, [high[0], y, height], spec.robot.top_down_rpy), (env_id, y)
        finally:
            env.close()


def test_sparse_compute_reward_is_the_distance_rule_over_a_batch():
    """HER relabels a batch: -1 unless the puck is within the 5 cm tolerance of the goal, row by row."""
    env = gym.make("VX300SSlideGoalSim-v0")
    try:
        _, info = env.reset(seed=0)
        rng = np.random.default_rng(0)
        achieved = rng.uniform(-0.3, 0.3, (64, 3))
        desired = achieved + rng.normal(0, 0.05, (64, 3))
        rewards = env.unwrapped.compute_reward(achieved, desired, np.array([info] * 64))
        expected = -(np.linalg.norm(achieved - desired, axis=1) > 0.05).astype(float)
        np.testing.assert_array_equal(rewards, expected)
    finally:
        env.close()


@pytest.mark.parametrize(
    "env_id, engine, at_least",
    [
        # a quick sample in the default run (the expert's 20-seed figure is the slow test below)
        ("VX300SSlideSim-v0", "pybullet", 0.5),
        # the strike itself, arm on puck, on each engine: the UR5e's fingers must meet the puck's side. Struck from
        # the Push family's height they met only its top rim: on MuJoCo the puck moved 5-9 cm and stopped, no seed
        # reached the goal, and PyBullet's reached it in 2 of these 4 (nothing else caught it: a kicked puck slides
        # on both engines)
        ("UR5eSlideSim-v0", "pybullet", 0.75),
        ("UR5eSlideSim-v0", "mujoco", 0.75),
    ],
)
def test_the_expert_strikes_the_puck_to_the_goal(env_id, engine, at_least):
    env = gym.make(env_id, engine=engine)
    try:
        results = run_episodes(env, make_policy("scripted", env), episodes=4, seed=0)
        assert success_rate(results) >= at_least, [(r.seed, r.length, r.success) for r in results]
    finally:
        env.close()


@pytest.mark.slow
@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
@pytest.mark.parametrize("env_id", SLIDE_IDS)
def test_the_expert_slides_over_20_seeds(env_id, engine):
    env = gym.make(env_id, engine=engine)
    try:
        results = run_episodes(env, make_policy("scripted", env), episodes=20, seed=0)
        assert success_rate(results) >= 0.7, [(r.seed, r.length) for r in results if not r.success]
    finally:
        env.close()


@pytest.mark.slow
@pytest.mark.parametrize("env_id", ["UR5eSlideGoalSim-v0", "PandaSlideGoalSim-v0"])
def test_in_ee_mode_two_legs_reach_more_goals_than_one_strike(env_id):
    """EE mode holds the striking face as it is: a long strike leaves off the line, and the expert's leave_short
    (stop short, strike again from there) is what its demonstrations in EE mode are collected with."""
    rates = {}
    for leave_short in (0.0, 0.15):
        env = gym.make(env_id, ee_action_type=True, overrides=[f"task.expert.params.leave_short={leave_short}"])
        try:
            rates[leave_short] = success_rate(run_episodes(env, make_policy("scripted", env), episodes=30, seed=0))
        finally:
            env.close()
    assert rates[0.15] >= rates[0.0] + 0.15 and rates[0.15] >= 0.55, rates


@pytest.mark.parametrize(
    "override, message",
    [
        ("task.objects.puck.shape=box", "task.objects.puck.height: a box is a cube of edge 'size'"),
        ("task.goal.achieved=ee.position", "task.goal.within_reach: the EE is the arm's own"),
    ],
)
def test_shape_and_reach_mistakes_are_named(override, message):
    with pytest.raises(SpecError, match=message.replace("(", r"\(").replace(")", r"\)")):
        envfactory.blueprint("VX300SSlideSim-v0", [override])


def test_a_puck_past_the_floors_edge_ends_the_episode_before_its_observation_leaves_its_box():
    """The floor ends 3 m from the origin, and so does a struck puck's observation box: a puck beyond it falls
    for ever, and the step that finds it there ends the episode, naming it, with the last observation inside its
    box (it was clipped into a valid-looking one before: the 10k-step bounds test, VX300SSlideGoalSim-v0)."""
    env = gym.make("VX300SSlideSim-v0")
    try:
        env.reset(seed=0)
        unwrapped = env.unwrapped
        backend = unwrapped.backend
        body = backend.objects["puck"]
        p.resetBasePositionAndOrientation(body, [3.05, 0.0, 0.015], [0, 0, 0, 1], physicsClientId=backend.client)
        hold = unwrapped.actions.to_policy(unwrapped.actions.hold_action(unwrapped.state))
        observation, _, terminated, truncated, info = env.step(hold)
        assert (terminated, truncated) == (False, True)
        assert "object puck is at [3.05, 0.0," in info["abort_reason"] and "off the floor" in info["abort_reason"]
        assert env.observation_space.contains(observation) and not info["observation_clipped"]
    finally:
        env.close()


@pytest.mark.slow
@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_a_yaw_row_lets_the_ee_mode_expert_square_its_face(engine):
    """With ee_yaw_action the expert turns the striking face square to the puck→goal line, as joint mode does,
    and strikes once: it reaches more goals than EE mode holding the face (seeds 0-29: 83% / 97% on PyBullet /
    MuJoCo; holding it, with two legs, 73% / 67% over seeds 0-59)."""
    rates = {}
    for yaw in (False, True):
        env = gym.make("UR5eSlideGoalSim-v0", engine=engine, ee_action_type=True, ee_yaw_action=yaw)
        try:
            rates[yaw] = success_rate(run_episodes(env, make_policy("scripted", env), episodes=30, seed=0))
        finally:
            env.close()
    assert rates[True] >= max(0.75, rates[False]), rates
