"""The MuJoCo engine from the same specs: every Sim ID makes, resets and steps on it; the arm follows the
joint-synchronous line the safety check proved; out of contact it ends every step where PyBullet does
(PyBullet is the independent judge: another engine, another model built from the same URDF)."""

from __future__ import annotations

import time

import gymnasium as gym
import mujoco
import numpy as np
import pybullet as p
import pytest

import envfactory  # noqa: F401  (registers the IDs)
from devkit.oracles.cross_engine import MujocoJudge
from envfactory.backends.base import BackendError
from envfactory.backends.mujoco.backend import MujocoBackend
from envfactory.backends.mujoco.model import ROBOT_PREFIX
from envfactory.experts import make_policy
from envfactory.registration import registry

SIM_IDS = sorted(env_id for env_id, record in registry.records().items() if record.backend == "sim")


@pytest.mark.parametrize("env_id", SIM_IDS)
def test_every_sim_id_makes_resets_and_steps_on_mujoco(env_id):
    env = gym.make(env_id, engine="mujoco")
    try:
        assert isinstance(env.unwrapped.backend, MujocoBackend)
        observation, _ = env.reset(seed=1)
        assert env.observation_space.contains(observation)
        rng = np.random.default_rng(1)
        for _ in range(3):
            action = rng.uniform(env.action_space.low, env.action_space.high).astype(np.float32)
            observation, reward, terminated, truncated, info = env.step(action)
            assert env.observation_space.contains(observation), info["observation_clipped"]
            assert np.isfinite(reward)
    finally:
        env.close()


def _free_motions(env, seed: int, steps: int):
    """Accepted random steps (`env` made with full fidelity, so every cycle is one rollout): per step, the largest
    distance of any arm joint from the straight joint-space segment between where the step started and its
    target, over every substep the engine simulated."""
    unwrapped = env.unwrapped
    backend = unwrapped.backend
    arm = 1 + backend.handles.arm_qpos  # a full-physics state row is (time, qpos, qvel, ...)
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    for _ in range(steps):
        action = rng.uniform(env.action_space.low, env.action_space.high).astype(np.float32)
        state = unwrapped.state
        target = unwrapped.actions.translate(action, state).q_arm
        if env.step(action)[4]["action_rejected"]:
            continue
        start = state.q_arm
        q = backend.cycles._states[0][:, arm]
        way = target - start
        # the nearest point of the segment, whatever the timing along it
        fraction = np.clip((q - start) @ way / max(way @ way, 1e-12), 0.0, 1.0)[:, None]
        yield float(np.max(np.abs(q - (start + fraction * way))))


@pytest.mark.parametrize(
    "env_id", ["UR5eReacherSim-v0", "VX300SReacherSim-v0", "RX200ReacherSim-v0", "NED2ReacherSim-v0"]
)
def test_the_arm_stays_on_the_proven_line(env_id):
    """Out of contact every joint stays within 1 mrad of the commanded joint-space line at every substep
    (PyBullet's per-joint motors, each at its own speed, leave it: the joints arrive at different times)."""
    env = gym.make(env_id, engine="mujoco", physics_fidelity="full")
    try:
        deviations = list(_free_motions(env, seed=0, steps=25))
    finally:
        env.close()
    assert len(deviations) >= 10
    assert max(deviations) < 1e-3, max(deviations)


@pytest.mark.parametrize("env_id", ["UR5eReacherSim-v0", "VX300SReacherSim-v0", "NED2ReacherSim-v0"])
def test_out_of_contact_the_engines_agree_within_a_millimetre(env_id):
    engines = [gym.make(env_id), gym.make(env_id, engine="mujoco")]
    try:
        for env in engines:
            env.reset(seed=4)
        rng = np.random.default_rng(4)
        for _ in range(100):
            action = rng.uniform(engines[0].action_space.low, engines[0].action_space.high).astype(np.float32)
            flags = [env.step(action)[4]["action_rejected"] for env in engines]
            assert flags[0] == flags[1]
        gap = np.linalg.norm(engines[0].unwrapped.state.ee_position - engines[1].unwrapped.state.ee_position)
        assert gap < 1e-3, gap
    finally:
        for env in engines:
            env.close()


def test_a_gui_on_mujoco_is_refused_with_the_engine_that_has_one():
    with pytest.raises(BackendError, match="engine='pybullet'"):
        gym.make("UR5eReacherSim-v0", engine="mujoco", gui=True)


def test_realtime_mode_paces_mujoco_steps_to_the_wall_clock():
    """realtime_mode=True lets each cycle last its simulated time (a lower bound only: load makes it longer)."""
    paced = gym.make("UR5eReacherSim-v0", engine="mujoco", realtime_mode=True, action_cycle_time=0.2)
    paced.reset(seed=0)
    started = time.perf_counter()
    for _ in range(3):
        paced.step(np.zeros(paced.action_space.shape, paced.action_space.dtype))
    assert time.perf_counter() - started >= 3 * 0.2 * 0.99
    paced.close()


def test_engine_is_refused_on_a_real_id():
    with pytest.raises(envfactory.SpecError, match="sim.engine"):
        gym.make("UR5eReacherReal-v0", engine="mujoco")


def _hold_still(fidelity: str, steps: int = 8):
    env = gym.make("VX300SPushSim-v0", engine="mujoco", physics_fidelity=fidelity)
    unwrapped = env.unwrapped
    try:
        env.reset(seed=0)
        for _ in range(steps):
            env.step(unwrapped.actions.hold_action(unwrapped.state))
        state = unwrapped.state
        cycle = round(unwrapped.blueprint.spec.env.timing.action_cycle_time / unwrapped.backend.cycles.dt)
        return (
            unwrapped.backend.cycle_counts,
            cycle,
            state.joint_positions.copy(),
            state.objects["cube"].position.copy(),
        )
    finally:
        env.close()


def test_a_scene_at_rest_costs_no_substeps_and_ends_where_full_dynamics_does():
    counts, cycle, joints, cube = _hold_still("fast")
    reference_counts, _, reference_joints, reference_cube = _hold_still("full")
    assert reference_counts is None  # full dynamics: every cycle simulated
    # the first cycle after a reset settles the scene: simulated only until the cube rests (a few chunks of
    # substeps, not the cycle), then the arm placed; the other seven cost no substep
    assert counts.at_rest == 7 and counts.kinematic == 1 and counts.dynamic == 0
    assert 0 < counts.substeps <= cycle / 2
    assert np.max(np.abs(joints - reference_joints)) < 1e-4
    assert np.linalg.norm(cube - reference_cube) < 5e-5


def _closest_approach(env_id: str, seed: int, steps: int, saturated: bool = False) -> tuple[float, int]:
    """The smallest distance MuJoCo measures between a moving robot geom and a scene obstacle, over every substep of
    every accepted step (MuJoCo's own distance queries judge, not the safety check's coal), and how many steps were
    accepted (full fidelity: every cycle is one rollout whose substeps are read). Random actions, or `saturated`: every
    row on a bound, held for a few steps, as a saturated policy drives the arm into the table's edge and its own
    links."""
    import mujoco

    env = gym.make(env_id, engine="mujoco", physics_fidelity="full")
    unwrapped = env.unwrapped
    model, backend = unwrapped.backend.model, unwrapped.backend
    scratch = mujoco.MjData(model)
    judge = MujocoJudge(model, 0.1)
    nq = model.nq
    rng = np.random.default_rng(seed)
    closest, accepted = np.inf, 0
    try:
        env.reset(seed=seed)
        for _ in range(steps):
            if not saturated:
                action = rng.uniform(env.action_space.low, env.action_space.high).astype(np.float32)
            elif _ % 4 == 0:
                action = np.where(
                    rng.random(env.action_space.shape) < 0.5, env.action_space.low, env.action_space.high
                ).astype(np.float32)
            if env.step(action)[4]["action_rejected"]:
                continue
            accepted += 1
            for row in backend.cycles._states[0][::4]:
                scratch.qpos[:] = row[1 : 1 + nq]
                mujoco.mj_kinematics(model, scratch)
                closest = min(closest, judge.lowest_in(scratch)[0])
    finally:
        env.close()
    return closest, accepted


@pytest.mark.parametrize("saturated", [False, True], ids=["random", "saturated"])
@pytest.mark.parametrize("env_id", ["UR5ePnPSim-v0", "VX300SPushSim-v0", "NED2ReacherSim-v0"])
def test_no_accepted_step_brings_the_simulated_arm_within_the_margin(env_id, saturated):
    closest, accepted = _closest_approach(env_id, seed=2, steps=40, saturated=saturated)
    margin = envfactory.blueprint(env_id).spec.env.safety.surface_margin
    assert accepted >= 10
    assert closest >= margin - 1e-3, (closest, margin)


def test_rendering_works_or_names_what_is_missing():
    """Where an OpenGL context can be had, rgb_array and camera images render; where none can (this headless
    machine), make and render say which MUJOCO_GL to set, and the process lives on (a retry inside MuJoCo's
    GL setup would abort it)."""
    env = gym.make("UR5eReacherSim-v0", engine="mujoco", render_mode="rgb_array")
    try:
        env.reset(seed=0)
        try:
            image = env.render()
        except BackendError as exc:
            assert "MUJOCO_GL" in str(exc)
            with pytest.raises(BackendError, match="MUJOCO_GL"):
                gym.make("UR5ePnPSim-v0", engine="mujoco", use_kinect=True)
            with pytest.raises(BackendError, match="MUJOCO_GL"):
                env.render()
        else:
            assert image.shape == (360, 480, 3) and image.dtype == np.uint8
            camera_env = gym.make("UR5ePnPSim-v0", engine="mujoco", use_kinect=True)
            observation, _ = camera_env.reset(seed=0)
            assert camera_env.observation_space.contains(observation)
            camera_env.close()
    finally:
        env.close()


def test_a_kinematic_cycle_leaves_the_frames_mj_forward_would():
    """A kinematic cycle computes frames, cameras and lights, not contacts and forces: every pose a reader uses
    (the objects' and the arm's bodies, geoms, sites, cameras and lights) is what MuJoCo's full mj_forward gives
    for the same state."""
    import mujoco

    env = gym.make("UR5ePnPSim-v0", engine="mujoco")
    try:
        env.reset(seed=0)
        env.action_space.seed(0)
        backend = env.unwrapped.backend
        model, data = backend.model, backend.data
        checked = 0
        for _ in range(40):
            before = backend.cycles.counts.kinematic
            env.step(env.action_space.sample())
            if backend.cycles.counts.kinematic == before:
                continue
            full = mujoco.MjData(model)
            full.qpos[:], full.qvel[:], full.ctrl[:] = data.qpos, data.qvel, data.ctrl
            full.mocap_pos[:], full.mocap_quat[:] = data.mocap_pos, data.mocap_quat
            mujoco.mj_forward(model, full)
            for name in (
                "xpos",
                "xmat",
                "xquat",
                "geom_xpos",
                "geom_xmat",
                "site_xpos",
                "cam_xpos",
                "cam_xmat",
                "light_xpos",
                "light_xdir",
                "xanchor",
                "xaxis",
            ):
                np.testing.assert_allclose(getattr(data, name), getattr(full, name), rtol=0, atol=1e-12, err_msg=name)
            checked += 1
        assert checked >= 10, checked  # random actions out of contact: most cycles are kinematic
    finally:
        env.close()


ROBOT_IDS = ["UR5ePushSim-v0", "VX300SPushSim-v0", "RX200PushSim-v0", "NED2PushSim-v0", "PandaPushSim-v0"]


@pytest.mark.parametrize("env_id", ROBOT_IDS)
def test_every_servo_pushes_the_specs_effort_and_no_more(env_id):
    """Each servo, commanded far past where its joint is, pushes exactly the spec's effort (the force PyBullet's
    motors get). MuJoCo's URDF import had made each URDF effort the joint's force limit as well: the Ned2's jaws
    pushed 1 N of their 2 N, the Panda's fingers 20 of 70, the UR5e's wrists 28 N m of 150."""
    env = gym.make(env_id, engine="mujoco")
    try:
        env.reset(seed=0)
        robot, backend = env.unwrapped.blueprint.spec.robot, env.unwrapped.backend
        model, data = backend.model, backend.data
        efforts = dict(zip((j.name for j in robot.arm_joints), robot.arm_efforts))
        efforts[robot.gripper.joint] = robot.gripper.force
        for joint, effort in efforts.items():
            actuator = model.actuator(f"servo:{joint}").id
            driven = model.actuator_trnid[actuator][0]
            dof, address = model.jnt_dofadr[driven], model.jnt_qposadr[driven]
            for far in (-10.0, 10.0):
                data.ctrl[actuator] = data.qpos[address] + far
                mujoco.mj_forward(model, data)
                assert data.qfrc_actuator[dof] == pytest.approx(np.sign(far) * effort, rel=1e-6), (joint, far)
    finally:
        env.close()


def _pad_squeeze(env) -> float:
    """The summed normal force, N, of the jaws' contacts on the cube, by the engine's own contact report."""
    backend = env.unwrapped.backend
    pads = env.unwrapped.blueprint.spec.robot.gripper.pads.links
    if env.unwrapped.blueprint.backend == "pybullet":
        links = {
            p.getJointInfo(backend.body, j, physicsClientId=backend.client)[12].decode(): j
            for j in range(p.getNumJoints(backend.body, physicsClientId=backend.client))
        }
        contacts = p.getContactPoints(backend.body, backend.objects["cube"], physicsClientId=backend.client)
        return sum(c[9] for c in contacts if c[3] in {links[name] for name in pads})
    model, data, force, total = backend.model, backend.data, np.zeros(6), 0.0
    cube = model.body("object:cube").id
    pad_bodies = {model.body(ROBOT_PREFIX + name).id for name in pads}
    for index in range(data.ncon):
        bodies = {model.geom_bodyid[data.contact[index].geom1], model.geom_bodyid[data.contact[index].geom2]}
        if cube in bodies and bodies & pad_bodies:
            mujoco.mj_contactForce(model, data, index, force)
            total += force[0]
    return total


@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_a_held_cube_is_squeezed_with_the_grippers_force_on_both_engines(engine):
    """Statics: two jaws coupled one-to-one and driven by one motor squeeze a held cube with the motor's force in
    all, whichever jaw it pushes. The Ned2's cube, lifted by its Flip expert, on each engine: 2 N. MuJoCo's had
    1 N (the URDF's effort capped the servo), and its cube slipped out during the turn in every seed."""
    env = gym.make("NED2FlipSim-v0", engine=engine)
    try:
        policy = make_policy("scripted", env)
        observation, _ = env.reset(seed=0)
        for _ in range(32):  # grasped at about step 24, lifted by 32
            observation, *_ = env.step(policy(observation))
        assert env.unwrapped.state.objects["cube"].position[2] > 0.04, "the expert has not lifted the cube"
        force = env.unwrapped.blueprint.spec.robot.gripper.force
        assert _pad_squeeze(env) == pytest.approx(force, rel=0.05)
    finally:
        env.close()
