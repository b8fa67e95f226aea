"""Push and Pick-and-Place: the cube, the grasp, the lift stage and HER-exact rewards, in real physics."""

import numpy as np
import pytest

from envfactory.experts import make_policy

CUBE = slice(30, 33)  # cube position columns of the UR5e Push observation


def rollout(make, env_id, seed, steps=6, **kwargs):
    env = make(env_id, **kwargs)
    env.action_space.seed(11)
    first, _ = env.reset(seed=seed)
    trace = [first]
    for _ in range(steps):
        trace.append(env.step(env.action_space.sample())[:2])
    return trace, env.unwrapped


@pytest.mark.parametrize("env_id", ["UR5ePushSim-v0", "VX300SPnPGoalSim-v0"])
def test_same_seed_same_cube_and_trajectory(env_id, make):
    (a, env_a), (b, env_b) = rollout(make, env_id, 42), rollout(make, env_id, 42)
    assert repr(a) == repr(b)
    assert np.array_equal(env_a.state.objects["cube"].position, env_b.state.objects["cube"].position)


def test_cube_spawn_is_random_within_the_offset_and_fixed_without(make):
    env = make("UR5ePushSim-v0").unwrapped
    spawns = []
    for seed in range(8):
        observation, _ = env.reset(seed=seed)
        spawns.append(observation[CUBE])
    spawns = np.array(spawns)
    default = np.array([0.5, -0.15, 0.795])
    assert len({tuple(s) for s in spawns.round(4)}) == 8, "each seed spawns the cube somewhere else"
    assert np.all(np.abs(spawns[:, :2] - default[:2]) <= 0.05 + 1e-4)
    np.testing.assert_allclose(spawns[:, 2], 0.795, atol=2e-3)  # resting on the table top

    fixed = make("UR5ePushSim-v0", random_cube_spawn=False).unwrapped
    for seed in (1, 2):
        observation, _ = fixed.reset(seed=seed)
        np.testing.assert_allclose(observation[CUBE], default, atol=2e-3)


def test_cube_is_respawned_at_rest(make):
    env = make("UR5ePushSim-v0", random_cube_spawn=False)
    env.reset(seed=0)
    policy = make_policy("scripted", env)
    for _ in range(25):  # push the cube away
        env.step(policy(None))
    moved = env.unwrapped.state.objects["cube"].position.copy()
    assert np.linalg.norm(moved[:2] - [0.5, -0.15]) > 0.03
    observation, _ = env.reset(seed=0)
    np.testing.assert_allclose(observation[CUBE], [0.5, -0.15, 0.795], atol=2e-3)
    np.testing.assert_array_equal(observation[36:42], 0.0)  # no velocity carried over
    observation, *_ = env.step(np.zeros(6, dtype=np.float32))
    np.testing.assert_allclose(observation[36:42], 0.0, atol=1e-3)  # and none gained at rest


def test_finite_difference_velocity_matches_displacement(make):
    env = make("UR5ePushSim-v0", random_cube_spawn=False)
    env.reset(seed=3)
    policy = make_policy("scripted", env)
    before = env.unwrapped.state.objects["cube"].position.copy()
    for _ in range(20):
        observation, *_ = env.step(policy(None))
        after = observation[CUBE].astype(float)
        np.testing.assert_allclose(observation[36:39], (after - before) / 0.5, atol=1e-4)
        before = after


@pytest.mark.parametrize("env_id", ["UR5ePnPSim-v0", "VX300SPnPSim-v0"])
def test_is_grasped_truth_table_from_physics(env_id, make):
    """open/closed × near/far, each reached by moving the real arm and gripper."""
    env = make(env_id, random_cube_spawn=False)
    unwrapped = env.unwrapped
    gripper = unwrapped.blueprint.spec.robot.gripper
    grasp_column = unwrapped.observations.size - 1

    observation, _ = env.reset(seed=0)
    assert observation[grasp_column] == 0.0  # open, far

    hold_closed = np.zeros(env.action_space.shape, dtype=np.float32)
    hold_closed[-1] = gripper.closed
    for _ in range(4):
        observation, *_ = env.step(hold_closed)
    assert gripper.closure(unwrapped.state.gripper) > 0.9
    assert observation[grasp_column] == 0.0  # closed, far

    observation, _ = env.reset(seed=0)
    policy = make_policy("scripted", env)
    spawn_z = unwrapped.spawner.objects["cube"].spawn.position[2]
    open_near = None
    for _ in range(80):
        action = policy(observation)
        if policy.phase == "close" and open_near is None:
            open_near = observation[grasp_column]  # the fingers around the cube, still open
            assert gripper.closure(unwrapped.state.gripper) < 0.1
        observation, *_ = env.step(action)
        if policy.phase == "carry":
            break
    assert open_near == 0.0
    assert observation[grasp_column] == 1.0  # closed, near: held
    lifted = unwrapped.state.objects["cube"].position[2] - spawn_z
    assert lifted > 0.1, "the cube rises with the gripper: the grasp holds in physics"


def test_grasp_direction_comes_from_open_and_closed_values():
    import envfactory
    from envfactory.terms.grasp import bind_grasp
    from envfactory.terms.library import TermContext

    for env_id, holding, loose in (("UR5ePnPSim-v0", 0.45, 0.2), ("VX300SPnPSim-v0", 0.0335, 0.04)):
        spec = envfactory.blueprint(env_id).spec
        layout = TermContext(spec.robot, spec.task, 7, np.zeros(7), np.ones(7))
        test = bind_grasp(layout, bind_grasp.__globals__["GraspParams"](object="cube"))
        assert spec.robot.gripper.closure(holding) >= test.closure > spec.robot.gripper.closure(loose)


def test_lift_stage_leads_then_hands_over_to_the_place_goal(make):
    env = make("UR5ePnPSim-v0", random_cube_spawn=False)
    unwrapped = env.unwrapped
    observation, info = env.reset(seed=5)
    spawn = np.array([0.5, -0.15, 0.795])
    lift_goal = spawn + [0, 0, 0.15]
    assert info["intermediate_active"] == 1.0
    np.testing.assert_allclose(info["intermediate_goal"], lift_goal)
    cube = observation[31:34]
    assert observation[9] == pytest.approx(np.linalg.norm(lift_goal - cube), abs=1e-4)  # columns follow the lift goal
    policy = make_policy("scripted", env)
    switched = None
    for step in range(40):
        observation, _, _, _, info = env.step(policy(None))
        if info["intermediate_active"] == 0.0:
            switched = step
            break
    assert switched is not None, "the expert lifts the cube to the lift goal"
    cube = observation[31:34]
    assert np.linalg.norm(cube - lift_goal) < 0.05
    assert observation[9] == pytest.approx(np.linalg.norm(unwrapped.goal - cube), abs=1e-4)

    flat = make("UR5ePnPSim-v0", multi_goal=False)
    observation, info = flat.reset(seed=5)
    assert "intermediate_active" not in info or info["intermediate_active"] == 0.0
    assert observation[9] == pytest.approx(np.linalg.norm(flat.unwrapped.goal - observation[31:34]), abs=1e-4)


def test_lift_height_kwarg_moves_the_lift_goal(make):
    env = make("VX300SPnPSim-v0", random_cube_spawn=False, lift_height=0.1)
    _, info = env.reset(seed=0)
    np.testing.assert_allclose(info["intermediate_goal"], [0.25, 0.0, 0.115])


@pytest.mark.parametrize("env_id", ["UR5ePnPGoalSim-v0", "VX300SPushGoalSim-v0"])
def test_compute_reward_matches_step_rewards_along_an_expert_episode(env_id, make):
    # Dense brings in the lift stage and the grasp bonus: both recorded in info at step time
    env = make(env_id, reward_type="Dense")
    observation, _ = env.reset(seed=8)
    policy = make_policy("scripted", env)
    achieved, desired, infos, rewards = [], [], [], []
    for _ in range(40):
        observation, reward, _, _, info = env.step(policy(observation))
        achieved.append(observation["achieved_goal"])
        desired.append(observation["desired_goal"])
        infos.append(info)
        rewards.append(reward)
    infos = np.array(infos)
    batch = env.unwrapped.compute_reward(np.array(achieved), np.array(desired), infos)
    np.testing.assert_allclose(batch, rewards, rtol=1e-5, atol=1e-5)
    if "Pn" in env_id:
        assert any(i["is_grasped"] for i in infos) and any(i["intermediate_active"] == 0 for i in infos)
    # HER relabelling: the achieved cube position as the goal is worth the reached bonus, step by step
    relabelled = env.unwrapped.compute_reward(np.array(achieved), np.array(achieved), infos)
    final_stage = np.array([i.get("intermediate_active", 0.0) == 0.0 for i in infos])
    missed = np.array([not i["is_success"] for i in infos]) & final_stage
    assert np.all(relabelled[missed] >= np.array(rewards)[missed] + 20.0 - 1e-6)


@pytest.mark.parametrize("env_id", ["UR5ePushSim-v0", "VX300SPnPGoalSim-v0"])
def test_use_kinect_adds_headless_camera_images(env_id, make):
    env = make(env_id, use_kinect=True)
    observation, _ = env.reset(seed=0)
    assert {"observation", "rgb", "depth"} <= set(observation)
    assert observation["rgb"].shape == (96, 128, 3) and observation["rgb"].dtype == np.uint8
    assert observation["depth"].shape == (96, 128) and observation["depth"].dtype == np.float32
    assert env.observation_space.contains(observation)
    assert observation["rgb"].std() > 5
    # the table top is nearer the camera than the floor beyond it
    assert observation["depth"][60, 64] < observation["depth"][5, 64]
    plain, _ = make(env_id).reset(seed=0)
    flat = plain if isinstance(plain, np.ndarray) else plain["observation"]
    np.testing.assert_array_equal(observation["observation"], flat)


@pytest.mark.parametrize(
    "env_id, engine",
    [
        ("UR5ePnPSim-v0", "pybullet"),
        ("VX300SPnPSim-v0", "pybullet"),
        ("UR5ePnPSim-v0", "mujoco"),
        ("NED2PnPSim-v0", "mujoco"),
    ],
)
def test_lifted_cube_stays_in_the_fingers(env_id, engine, make):
    """Held 20 s in the air, then swung: the contact parameters in the robot YAML keep the grip (on MuJoCo also
    its mimic constraints' stiffness, and the Ned2's spec without the no-slip pass)."""
    env = make(env_id, random_cube_spawn=False, engine=engine)
    unwrapped = env.unwrapped
    observation, _ = env.reset(seed=1)
    policy = make_policy("scripted", env)
    while policy.phase != "carry":
        observation, *_ = env.step(policy(observation))

    def in_gripper():  # the cube's place in the gripper's frame: slip, not the arm's own sag
        state = unwrapped.state
        return state.ee_rotation.T @ (state.objects["cube"].position - state.ee_position)

    held = in_gripper()
    hold = np.zeros(env.action_space.shape, dtype=np.float32)
    hold[-1] = unwrapped.blueprint.spec.robot.gripper.closed
    for step in range(50):
        swing = hold.copy()
        if step >= 40:
            swing[0] = 2.0 if step % 2 else -2.0  # base swings of 0.1 rad per step
        env.step(swing)
    drift = in_gripper() - held
    assert np.linalg.norm(drift) < 0.015, drift
