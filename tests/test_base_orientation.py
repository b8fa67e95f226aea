"""A robot base turned by `mount_rpy` is honoured everywhere: kinematics, the simulated arm, the
task frame of objects and goals, the derived bounds and the safety check.

The oracle is PyBullet, which places the base from its own reading of the rpy
(`getQuaternionFromEuler`) and measures with its own collision shapes; the rotations
below are written out with numpy, never with envfactory's frame code.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pybullet as p
import pytest

import envfactory
from devkit.oracles.bullet_judge import BulletJudge, judge_steps
from envfactory.envs import RobotEnv
from envfactory.schema.errors import SpecError

# (ID, overrides): a yawed VX300S whose task frame is its base (goals and objects turn with it),
# and a UR5e tilted on all three axes, its task frame the world
TURNED = {
    "vx300s-yaw": ("VX300SPushSim-v0", ["+robot.mount_rpy=[0.0,0.0,0.7]"]),
    "ur5e-tilt": (
        "UR5eReacherSim-v0",
        ["+robot.mount_rpy=[0.15,-0.1,0.5]", "robot.pedestal=null", "task.goal.box=[[0.4,0.0,0.9],[0.7,0.3,1.1]]"],
    ),
}


def rz(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def bullet_rotation(quaternion) -> np.ndarray:
    return np.array(p.getMatrixFromQuaternion(quaternion)).reshape(3, 3)


@pytest.fixture(scope="module", params=sorted(TURNED))
def turned(request):
    env_id, overrides = TURNED[request.param]
    env = RobotEnv(envfactory.blueprint(env_id, overrides))
    yield env
    env.close()


def _links(env) -> dict[str, int]:
    backend = env.backend
    return {
        p.getJointInfo(backend.body, j, physicsClientId=backend.client)[12].decode(): j
        for j in range(p.getNumJoints(backend.body, physicsClientId=backend.client))
    }


def _to_task(env, world_position) -> np.ndarray:
    """The task frame by hand: the world, or the base at `mount` turned by yaw only."""
    robot = env.blueprint.spec.robot
    if robot.task_frame == "world":
        return np.asarray(world_position, float)
    return rz(robot.mount_rpy[2]).T @ (np.asarray(world_position, float) - np.asarray(robot.mount))


def test_every_link_and_the_ee_sit_where_pybullet_puts_them(turned):
    env, rng = turned, np.random.default_rng(0)
    backend, kin = env.backend, env.kinematics
    model = kin.model
    mount = np.asarray(env.blueprint.spec.robot.mount)
    links = _links(env)
    shared = [name for name in links if model.existFrame(name)]
    assert len(shared) >= 8
    boxes = env.blueprint.boxes
    worst_link, worst_ee = 0.0, 0.0
    for _ in range(25):
        q = rng.uniform(kin.arm_lower, kin.arm_upper)
        backend._set_joint_state(q, None)
        pin_data = model.createData()
        pin.framesForwardKinematics(model, pin_data, kin.full_q(q, backend.robot.gripper.open))
        for name in shared:
            state = p.getLinkState(
                backend.body, links[name], computeForwardKinematics=1, physicsClientId=backend.client
            )
            placement = pin_data.oMf[model.getFrameId(name)]
            worst_link = max(
                worst_link,
                np.abs(mount + placement.translation - state[4]).max(),
                np.abs(placement.rotation - bullet_rotation(state[5])).max(),
            )
        ee_state = p.getLinkState(
            backend.body,
            links[env.blueprint.spec.robot.ee_frame],
            computeForwardKinematics=1,
            physicsClientId=backend.client,
        )
        position, rotation = kin.ee_pose(q, backend.robot.gripper.open)
        expected = _to_task(env, ee_state[4])
        worst_ee = max(worst_ee, np.abs(position - expected).max())
        # the derived observation box holds every EE position the arm can reach
        assert np.all(expected >= boxes.ee.low - 1e-6) and np.all(expected <= boxes.ee.high + 1e-6)
    assert worst_link < 1e-5, worst_link
    assert worst_ee < 1e-5, worst_ee


def test_ik_reaches_task_frame_points_pybullet_confirms(turned):
    env = turned
    kin, backend = env.kinematics, env.backend
    low, high = (np.asarray(b, float) for b in env.blueprint.spec.task.goal.box)
    ee = _links(env)[env.blueprint.spec.robot.ee_frame]
    for target in (low, high, (low + high) / 2):
        solution = kin.solve_ik(env.home, target)
        assert solution.success
        backend._set_joint_state(solution.q_arm, None)
        state = p.getLinkState(backend.body, ee, computeForwardKinematics=1, physicsClientId=backend.client)
        np.testing.assert_allclose(_to_task(env, state[4]), target, atol=1e-3)


def test_collision_clearances_agree_with_pybullet_distances(turned):
    """coal's clearance of every link-obstacle pair against Bullet's closest points, base turned."""
    env, rng = turned, np.random.default_rng(1)
    collision = env.safety.collision
    judge = BulletJudge(env, 0.0)
    try:
        links = {
            p.getJointInfo(judge.body, j, physicsClientId=judge.client)[12].decode(): j
            for j in range(p.getNumJoints(judge.body, physicsClientId=judge.client))
        }
        links[p.getBodyInfo(judge.body, physicsClientId=judge.client)[0].decode()] = -1
        # the check widens the table top sideways; Bullet gets the same boxes the check uses
        obstacles = [
            p.createMultiBody(
                0,
                p.createCollisionShape(p.GEOM_BOX, halfExtents=list(o.half_extents), physicsClientId=judge.client),
                basePosition=list(o.center),
                physicsClientId=judge.client,
            )
            for o in collision.obstacles
        ]
        compared, worst = 0, 0.0
        scene = len(collision.scene_shape)
        for _ in range(15):
            q = rng.uniform(env.kinematics.arm_lower, env.kinematics.arm_upper)
            gripper = env.blueprint.spec.robot.gripper.open
            judge.pose(q, gripper)
            collision.pose(q, gripper)
            ours = collision.exact(np.arange(scene))
            lowest: dict[tuple[str, int], float] = {}
            for pair in range(scene):
                shape = collision.shapes[collision.scene_shape[pair]]
                key = (shape.link, int(collision.scene_obstacle[pair]))
                lowest[key] = min(lowest.get(key, np.inf), ours[pair] + shape.padding)
            for (link, obstacle), value in lowest.items():
                if value > 0.3:
                    continue  # far pairs: Bullet answers only within its query distance
                points = p.getClosestPoints(
                    judge.body, obstacles[obstacle], 0.5, linkIndexA=links[link], physicsClientId=judge.client
                )
                bullet = min(point[8] for point in points)
                worst = max(worst, abs(bullet - value))
                compared += 1
        assert compared > 20
        # Bullet pads each convex shape by its collision margin (about 1 mm, measured in #9)
        assert worst < 0.003, worst
    finally:
        judge.close()


def test_objects_and_goals_turn_with_a_base_task_frame():
    env = RobotEnv(envfactory.blueprint(*TURNED["vx300s-yaw"]))
    try:
        robot, table = env.blueprint.spec.robot, env.blueprint.spec.scene.table
        turn, mount = rz(robot.mount_rpy[2]), np.asarray(robot.mount)
        for seed in range(5):
            env.reset(seed=seed)
            backend = env.backend
            world, quaternion = p.getBasePositionAndOrientation(backend.objects["cube"], physicsClientId=backend.client)
            state = env.state.objects["cube"]
            np.testing.assert_allclose(state.position, turn.T @ (np.asarray(world) - mount), atol=1e-9)
            # an unturned cube in the task frame is turned by the yaw in the world
            np.testing.assert_allclose(state.rotation, turn.T @ bullet_rotation(quaternion), atol=1e-6)
            # spawned on the table, inside its edges, in the world
            half = env.blueprint.spec.task.objects["cube"].size / 2
            assert abs(world[2] - (table.top_z + half)) < 2e-3
            corners = np.abs(turn[:2, :2]) @ [half, half]
            assert np.all(np.abs(np.asarray(world[:2]) - table.center) <= np.asarray(table.size) / 2 - corners + 1e-9)
            marker, _ = p.getBasePositionAndOrientation(backend._goal_marker, physicsClientId=backend.client)
            np.testing.assert_allclose(marker, mount + turn @ env._goal, atol=1e-9)
    finally:
        env.close()


@pytest.mark.parametrize("name", sorted(TURNED))
def test_accepted_steps_keep_the_margin_by_pybullet(name):
    env = RobotEnv(envfactory.blueprint(*TURNED[name]))
    try:
        for policy in ("random", "down"):
            result = judge_steps(env, policy, 30, seed=3)
            assert result["violations"] == [], result["violations"][:3]
            assert result["accepted"] > 0
    finally:
        env.close()


@pytest.mark.parametrize("overrides, words", [(["+robot.mount_rpy=[0.2,0.0,0.0]"], "needs 'task_frame: world'")])
def test_a_tilted_base_task_frame_is_refused_with_the_line(overrides, words):
    with pytest.raises(SpecError) as error:
        envfactory.blueprint("VX300SReacherSim-v0", overrides)
    assert "robot.mount_rpy" in str(error.value) and words in str(error.value)


def test_a_tilted_base_on_a_pedestal_is_refused():
    with pytest.raises(SpecError, match="cannot stand on a pedestal"):
        envfactory.blueprint("UR5eReacherSim-v0", ["+robot.mount_rpy=[0.0,0.2,0.0]"])


@pytest.mark.slow
@pytest.mark.parametrize("policy", ["random", "down", "extremes", "repeated"])
@pytest.mark.parametrize("name", sorted(TURNED))
def test_many_steps_keep_the_margin_by_pybullet(name, policy):
    env = RobotEnv(envfactory.blueprint(*TURNED[name]))
    try:
        result = judge_steps(env, policy, 400, seed=7)
        print(name, policy, {k: v for k, v in result.items() if k != "violations"})
        assert result["violations"] == [], result["violations"][:3]
    finally:
        env.close()
