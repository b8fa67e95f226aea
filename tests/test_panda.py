"""The Panda against panda-gym, its oracle: the same robot on the same table, so that the two can be set side by side.

panda-gym's world has its table top at z 0; the Panda families stand the same table on the floor, 0.4 m up
(robots/panda.yaml), so every height here is panda-gym's plus 0.4 m.
"""

import gymnasium as gym
import numpy as np
import pybullet as p
import pytest

import envfactory

panda_gym = pytest.importorskip("panda_gym", reason="panda-gym is the [bench] extra (part of [test])")

LIFT = np.array([0.0, 0.0, 0.4])


@pytest.fixture
def twins():
    made = []

    def make(*ids):
        envs = [gym.make(env_id) for env_id in ids]
        made.extend(envs)
        return envs

    yield make
    for env in made:
        env.close()


def test_home_puts_the_hand_where_panda_gym_puts_it(twins):
    ours, theirs = twins("PandaReachSim-v0", "PandaReach-v3")
    ours.reset(seed=0)
    observation, _ = theirs.reset(seed=0)
    np.testing.assert_allclose(ours.unwrapped.state.ee_position, observation["observation"][:3] + LIFT, atol=1e-6)


def test_the_table_is_panda_gyms(twins):
    ours, theirs = twins("PandaPushSim-v0", "PandaPush-v3")
    ours.reset(seed=0)
    theirs.reset(seed=0)
    sim = theirs.unwrapped.sim
    low, high = np.array(sim.physics_client.getAABB(sim._bodies_idx["table"]))
    backend = ours.unwrapped.backend
    our_low, our_high = np.array(p.getAABB(backend._table_body, physicsClientId=backend.client))
    # panda-gym's table is one box down to its floor; ours is a top on legs: the tops must coincide
    np.testing.assert_allclose(our_high, high + LIFT, atol=1e-6)
    np.testing.assert_allclose(our_low[:2], low[:2], atol=1e-6)


@pytest.mark.parametrize(
    "ours_id, theirs_id", [("PandaPushSim-v0", "PandaPush-v3"), ("PandaPnPSim-v0", "PandaPickAndPlace-v3")]
)
def test_cubes_and_goals_fill_panda_gyms_ranges(twins, ours_id, theirs_id):
    """Over 60 resets, our cube spawns and goals lie in the boxes panda-gym's task samples from (its object's
    centre half an edge above the table, plus its ranges) and fill at least 80% of each side."""
    ours, theirs = twins(ours_id, theirs_id)
    task = theirs.unwrapped.task
    centre = np.array([0.0, 0.0, task.object_size / 2])
    boxes = {
        "spawn": (centre + task.obj_range_low, centre + task.obj_range_high),
        "goal": (centre + task.goal_range_low, centre + task.goal_range_high),
    }
    samples = {"spawn": [], "goal": []}
    for seed in range(60):
        ours.reset(seed=seed)
        samples["spawn"].append(ours.unwrapped.state.objects["cube"].position - LIFT)
        samples["goal"].append(ours.unwrapped.goal - LIFT)
    for name, (low, high) in boxes.items():
        mine = np.array(samples[name])
        assert (mine >= low - 1e-6).all() and (mine <= high + 1e-6).all(), (name, mine.min(0), mine.max(0), low, high)
        wide = high - low > 0
        assert (np.ptp(mine, axis=0)[wide] >= 0.8 * (high - low)[wide]).all(), (name, np.ptp(mine, axis=0))


def test_a_real_id_on_the_panda_is_refused_with_the_reason():
    robot = envfactory.blueprint("PandaReachSim-v0").spec.robot
    assert robot.ros is None and "franka_ros" in robot.simulation_only


@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_both_engines_load_the_identified_inertia_in_place_of_the_placeholder(engine):
    """robots/panda.yaml replaces pybullet_data's 0.1 kg m^2 placeholders with identified mass properties: each
    engine, reading the assembled URDF itself, holds every overridden link's mass and principal moments."""
    import mujoco

    env = gym.make("PandaReachSim-v0", engine=engine)
    try:
        env.reset(seed=0)
        backend = env.unwrapped.backend
        inertials = env.unwrapped.blueprint.spec.robot.model.inertials
        assert {f"panda_link{i}" for i in range(1, 8)} <= set(inertials)
        for link, spec in inertials.items():
            ixx, iyy, izz, ixy, ixz, iyz = spec.inertia
            moments = np.linalg.eigvalsh(np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]]))
            if engine == "pybullet":
                index = next(
                    j
                    for j in range(p.getNumJoints(backend.body, physicsClientId=backend.client))
                    if p.getJointInfo(backend.body, j, physicsClientId=backend.client)[12].decode() == link
                )
                info = p.getDynamicsInfo(backend.body, index, physicsClientId=backend.client)
                mass, held = info[0], np.sort(info[2])
            else:
                body = mujoco.mj_name2id(backend.model, mujoco.mjtObj.mjOBJ_BODY, "robot/" + link)
                mass, held = backend.model.body_mass[body], np.sort(backend.model.body_inertia[body])
            assert mass == pytest.approx(spec.mass, rel=1e-6), (engine, link)
            np.testing.assert_allclose(held, moments, rtol=1e-4, atol=1e-9, err_msg=f"{engine} {link}")
    finally:
        env.close()


@pytest.mark.parametrize(
    "override, message",
    [
        (
            "+robot.model.inertials.panda_link9={mass:1.0,xyz:[0,0,0],inertia:[0.1,0.1,0.1,0,0,0]}",
            "robot.model.inertials.panda_link9: no link named 'panda_link9'",
        ),
        (
            "robot.model.inertials.panda_link5.inertia=[0.01,0.01,0.05,0,0,0]",
            "robot.model.inertials.panda_link5.inertia: no body has this inertia",
        ),
    ],
)
def test_an_inertial_override_that_cannot_be_is_named(override, message):
    with pytest.raises(envfactory.SpecError, match=message):
        envfactory.blueprint("PandaReachSim-v0", [override])
