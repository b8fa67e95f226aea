"""`sim.fidelity: fast` (the default) against full dynamics, the reference (PyBullet stepping every substep).

Tolerances (design.md, budgets): EE ≤ 1 mm, object ≤ 2 mm and ≤ 2°, the scripted experts' success unchanged.
Measured per step from identical states (paired steps), along whole random-action trajectories fed the
same actions, and as expert success per seed. The default suite runs a few episodes per ID;
`pytest -m slow tests/test_fidelity.py` runs more, and `python -m devkit.bench.fidelity` prints the distributions.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pybullet as p
import pytest

import envfactory
from devkit.oracles.fidelity_probe import (
    assert_within,
    expert_success,
    full_spread,
    paired_episode,
    read_scene,
    trajectory_gaps,
)
from envfactory.backends.pybullet.fast_cycles import SETTLE_SUBSTEPS
from envfactory.geometry.object_clearance import NEAR_CONTACT

SIM_IDS = sorted(i for i, r in envfactory.records().items() if r.backend == "sim" and "Goal" not in i)


def test_full_fidelity_is_the_reference_dynamics():
    env = gym.make("UR5ePushSim-v0", physics_fidelity="full")
    try:
        assert env.unwrapped.backend.cycle_counts is None  # nothing but substeps
    finally:
        env.close()


def test_the_reference_replays_from_a_saved_state():
    """The paired measure rests on this: a cycle simulated twice from one saved state ends alike."""
    env = gym.make("UR5ePushSim-v0", physics_fidelity="full")
    try:
        env.reset(seed=1)
        env.action_space.seed(1)
        backend = env.unwrapped.backend
        backend.command_joints(env.unwrapped.state.q_arm + 0.1, 0.2)
        saved = backend.save_state()
        readings = []
        for _ in range(2):
            backend.restore_state(saved)
            backend.advance(0.5)
            readings.append(read_scene(env))
        # a restored state replays to within 0.1 µm (the contact cache of a fresh cube is rebuilt):
        # four orders below the tolerances measured with it
        assert np.allclose(readings[0].q_arm, readings[1].q_arm, rtol=0, atol=1e-6)
        assert np.allclose(readings[0].objects["cube"][0], readings[1].objects["cube"][0], rtol=0, atol=1e-6)
        assert np.abs(readings[0].q_arm - env.unwrapped.state.q_arm).max() > 0.09  # the cycle did move the arm
    finally:
        env.close()


def test_a_dropped_cube_replays_from_a_saved_state():
    """In the UR5e PnP expert's seeds 6 and 7 the cube leaves the fingers, falls, strikes the table and
    tumbles against fingers and table at once. Each such cycle, replayed from the state saved before it,
    must end where it ended. PyBullet processes contact pairs in the order the last run left them unless
    told to sort them: the replays then ended 15.6 and 3.7 mm away."""
    from envfactory.experts import make_policy

    replays = []
    for seed in (6, 7):
        env = gym.make("UR5ePnPSim-v0", physics_fidelity="full")
        try:
            observation, _ = env.reset(seed=seed)
            expert = make_policy("scripted", env, seed=seed)
            backend = env.unwrapped.backend
            cube, advance, client = backend.objects["cube"], backend.advance, backend.client

            def cube_position():
                return np.array(p.getBasePositionAndOrientation(cube, physicsClientId=client)[0])

            def watched(seconds):
                saved, start = backend.save_state(), cube_position()
                advance(seconds)
                end = cube_position()
                if end[2] < start[2] - 0.03:  # it fell: replay the cycle from where it began
                    backend.restore_state(saved)
                    advance(seconds)
                    replays.append(np.abs(cube_position() - end).max())
                backend.drop_state(saved)

            backend.advance = watched
            for _ in range(100):
                observation, _, terminated, truncated, _ = env.step(expert(observation))
                if terminated or truncated:
                    break
        finally:
            env.close()
    assert len(replays) >= 2 and max(replays) < 1e-6, replays


def _settling_room(env_id: str) -> bool:
    """Whether the spec's cycle leaves the motors SETTLE_SUBSTEPS after the motion, which a kinematic cycle
    needs (the Panda's Slide moves for 0.3 s of its 0.5 s cycle: its every cycle is simulated)."""
    spec = envfactory.blueprint(env_id).spec
    return spec.env.timing.action_cycle_time - spec.env.timing.action_speed >= SETTLE_SUBSTEPS / spec.sim.physics_hz


@pytest.mark.parametrize("env_id", SIM_IDS)
def test_fast_steps_match_full_dynamics_from_the_same_state(env_id):
    gaps, _ = paired_episode(env_id, "random", seed=0, steps=40)
    assert_within(gaps, f"{env_id} random")
    if _settling_room(env_id):
        assert "kinematic" in gaps.kinds  # the fast path is taken, not only measured
    else:  # a motion that ends too late in its cycle to settle by the reading is always simulated
        assert "kinematic" not in gaps.kinds
    expert, success = paired_episode(env_id, "scripted", seed=0)
    assert_within(expert, f"{env_id} scripted")
    # the experts touch the cube: dynamics there (a Reach has no cube)
    assert "dynamic" in expert.kinds or envfactory.blueprint(env_id).spec.task.name == "reach"
    # the expert's episode (acting on the fast outcomes) succeeds exactly when its full-dynamics run does
    assert [success] == expert_success(env_id, "full", [0])


@pytest.mark.parametrize("env_id", ["NED2PnPSim-v0", "RX200PnPSim-v0"])
def test_a_cube_dropped_at_spawn_settles_before_the_arm_is_placed(env_id):
    """These specs spawn the cube 5 mm above the table (the original suite's cube_init_pos): it lands and comes to rest
    in about 50 substeps. The first cycle simulates only that much, then places the arm where a kinematic
    cycle does, and ends where full dynamics ends the whole cycle."""
    for seed in range(3):
        gaps, _ = paired_episode(env_id, "random", seed=seed, steps=1)
        assert gaps.kinds == ["kinematic"], (seed, gaps.kinds)
        assert_within(gaps, f"{env_id} first cycle, seed {seed}")


def test_a_motion_beside_a_joint_limit_gets_dynamics():
    """Random actions on the Ned2 (seed 4) take its shoulder to its lower limit and then 2 mrad off it: PyBullet's
    limit constraint and the motor leave the joint 1.8 mrad short of that target (1 mm at the EE), where a kinematic
    cycle would land it exactly. Motions that start or end that close to a limit are simulated."""
    gaps, _ = paired_episode("NED2PnPSim-v0", "random", seed=4, steps=95)
    assert_within(gaps, "NED2PnPSim-v0 random, seed 4")
    assert "kinematic" in gaps.kinds


def test_a_cycle_that_ends_before_the_arm_settles_stays_faithful():
    """With action_cycle_time barely above action_speed the motors are still closing in when the
    observation is read: the fast fidelity must not pretend the arm arrived."""
    gaps, _ = paired_episode("VX300SPushSim-v0", "random", seed=0, steps=20, action_cycle_time=0.25)
    assert_within(gaps, "VX300SPushSim-v0 with a 0.25 s cycle")


@pytest.mark.parametrize("env_id", SIM_IDS)
def test_random_trajectories_stay_within_tolerance(env_id):
    """A fast and a full env fed the same random actions: delta actions start from the pose the last step
    reached, so any offset the full arm ends with at every cycle (a motor that gives under gravity, a
    solver that has not converged) adds up along the trajectory."""
    assert_within(trajectory_gaps(env_id, seed=0, steps=50), env_id)


@pytest.mark.slow
@pytest.mark.parametrize("env_id", SIM_IDS)
def test_fidelity_over_many_episodes(env_id):
    for seed in range(5):
        for policy in ("random", "scripted"):
            gaps, _ = paired_episode(env_id, policy, seed=seed)
            assert_within(gaps, f"{env_id} {policy} seed {seed}")
        # a strike that tumbles the cube is chaotic: the bar is full dynamics' own spread there, where larger
        trajectory, spread = trajectory_gaps(env_id, seed=seed, steps=100), full_spread(env_id, seed=seed, steps=100)
        assert_within(trajectory, f"{env_id} trajectory seed {seed}", spread)
    # Seed by seed, an episode the expert only just wins or loses can go either way: the UR5e PnP
    # expert on seed 4 is refused at the safety margin for many steps in both fidelities, and one
    # escapes by a 0.1 mm difference. The success count over 20 seeds may move by one episode.
    seeds = list(range(1, 21))
    fast, full = expert_success(env_id, "fast", seeds), expert_success(env_id, "full", seeds)
    assert abs(sum(fast) - sum(full)) <= 1, (fast, full)


@pytest.mark.parametrize("env_id", ["UR5ePnPSim-v0", "VX300SPnPSim-v0"])
def test_motions_proven_clear_of_the_cube_are_clear_in_pybullet(env_id):
    """The kinematic path's proof against PyBullet's own distance queries: random motions around the
    cube; every motion the proof accepts keeps each moving link NEAR_CONTACT from the cube at 40
    poses along its straight joint-space line, the gripper anywhere in its range."""
    env = gym.make(env_id)
    try:
        env.reset(seed=0)
        u = env.unwrapped
        backend, client = u.backend, u.backend.client
        clearance = backend._fast.clearance
        moving_links = {
            u.safety.collision.shapes[i].link
            for i in range(len(u.safety.collision.shapes))
            if u.safety.collision.lever[i].any()
        }
        link_index = {
            p.getJointInfo(backend.body, j, physicsClientId=client)[12].decode(): j
            for j in range(p.getNumJoints(backend.body, physicsClientId=client))
        }
        links = [link_index[name] for name in moving_links]
        cube = backend.objects["cube"]
        radius = backend._object_radii[(cube, -1)]  # keyed by (body, link): -1 is a free object's base
        gripper = u.blueprint.spec.robot.gripper
        low, high = sorted((gripper.open, gripper.closed))
        rng = np.random.default_rng(0)
        accepted = refused = 0
        for _ in range(60):
            q_from = u.home + rng.uniform(-0.6, 0.6, u.home.size)
            q_to = q_from + rng.uniform(-0.3, 0.3, u.home.size)
            g_from, g_to = rng.uniform(low, high, 2)
            ee, _ = u.kinematics.ee_pose(q_from, g_from)
            centre = u.task_frame.to_world(ee) + rng.uniform(-0.12, 0.12, 3)
            p.resetBasePositionAndOrientation(cube, centre.tolist(), [0, 0, 0, 1], physicsClientId=client)
            if not clearance.motion_is_clear(
                q_from, g_from, q_to, g_to, centre[None], np.array([radius]), NEAR_CONTACT
            ):
                refused += 1
                continue
            accepted += 1
            for fraction in np.linspace(0.0, 1.0, 40):
                for g in (g_from, (g_from + g_to) / 2, g_to):
                    backend._set_joint_state(q_from + fraction * (q_to - q_from), g)
                    nearest = min(
                        (
                            point[8]
                            for link in links
                            for point in p.getClosestPoints(
                                backend.body, cube, 0.05, linkIndexA=link, physicsClientId=client
                            )
                        ),
                        default=np.inf,
                    )
                    # PyBullet pads convex shapes by up to a millimetre (safety.py SHAPE_TOLERANCE)
                    assert nearest >= NEAR_CONTACT - 0.001, (
                        f"accepted motion comes {nearest * 1e3:.1f} mm from the cube at {fraction:.0%}"
                    )
        assert accepted >= 5 and refused >= 5, (accepted, refused)  # the draw exercises both answers
    finally:
        env.close()


def test_the_first_env_of_a_process_measures_as_the_next_ones_do():
    """The first fast env of a process records the gripper's step response; a later one finds it recorded.
    The recording once ran in the env's own PyBullet session, and what it left there changed later
    contact-rich cycles: the paired measure of the UR5e PnP expert's seed 4 came out different in the
    first env of a process and in the next (it won in one, lost in the other)."""
    from envfactory.backends.pybullet import backend

    backend._GRIPPER_RESPONSES.clear()
    first, first_success = paired_episode("UR5ePnPSim-v0", "scripted", seed=4)
    assert backend._GRIPPER_RESPONSES  # the first env recorded it, the second finds it
    second, second_success = paired_episode("UR5ePnPSim-v0", "scripted", seed=4)
    assert first_success == second_success
    assert first.ee == second.ee and first.object_position == second.object_position and first.kinds == second.kinds
