"""The safety check against an independent judge, and the bounds it rests on.

The judge is PyBullet: its own distance queries on the simulated scene and on
the commanded motion posed in a second client (devkit/oracles/bullet_judge.py), never
the check's Pinocchio/coal model.
"""

import numpy as np
import pytest

import envfactory
from devkit.oracles.bullet_judge import ADVERSARIAL, POLICIES, BulletJudge, judge_steps
from envfactory.envs import RobotEnv
from envfactory.geometry.collision_pairs import StalePairs, checksum, fingerprint, read_pairs, write_pairs

SIM_IDS = [
    "UR5eReacherSim-v0",
    "UR5ePushSim-v0",
    "UR5ePnPSim-v0",
    "VX300SReacherSim-v0",
    "VX300SPushSim-v0",
    "VX300SPnPSim-v0",
    "RX200ReacherSim-v0",
    "RX200PushSim-v0",
    "RX200PnPSim-v0",
    "NED2ReacherSim-v0",
    "NED2PushSim-v0",
    "NED2PnPSim-v0",
    "PandaReachSim-v0",
    "PandaPushSim-v0",
    "PandaPnPSim-v0",
]


def make(env_id, **kwargs):
    return RobotEnv(envfactory.blueprint(env_id, **kwargs))


@pytest.fixture(scope="module", params=["UR5ePnPSim-v0", "VX300SPnPSim-v0"])
def env(request):
    environment = make(request.param)
    environment.reset(seed=0)
    yield environment
    environment.close()


def _judge(env_id, ee, steps, seed=0):
    results = {}
    for name in POLICIES:
        environment = make(env_id, ee_action_type=ee)
        try:
            results[name] = judge_steps(environment, name, steps, seed)
        finally:
            environment.close()
    return results


def _assert_judged(results, env_id, ee):
    for name, result in results.items():
        assert result["violations"] == [], f"{env_id} ee={ee} {name}: accepted steps Bullet finds inside the margin"
    refused = sum(results[name]["rejected"] for name in ADVERSARIAL)
    assert refused > 0, f"{env_id} ee={ee}: no adversarial action was ever refused"
    assert results["random"]["accepted"] > 0, f"{env_id} ee={ee}: random actions were all refused"


@pytest.mark.parametrize("ee", [False, True], ids=["joint", "ee"])
@pytest.mark.parametrize("env_id", SIM_IDS)
def test_accepted_steps_keep_the_margin_by_bullet(env_id, ee):
    """A few hundred steps per ID and mode: no accepted step comes within the margin, simulated or commanded."""
    _assert_judged(_judge(env_id, ee, steps=LONGER.get((env_id, ee), 50)), env_id, ee)


# Where 50 steps of each adversary never meet the check: the Ned2 Push in EE mode keeps its gripper down and
# clear, and its adversaries first reach the table after about 60 steps (its coarse old shapes refused
# motions Niryo's meshes show 37 mm clear, which made 50 look enough)
LONGER = {("NED2PushSim-v0", True): 100}


@pytest.mark.slow
@pytest.mark.parametrize("ee", [False, True], ids=["joint", "ee"])
@pytest.mark.parametrize("env_id", SIM_IDS)
def test_accepted_steps_keep_the_margin_by_bullet_10k(env_id, ee):
    _assert_judged(_judge(env_id, ee, steps=2500, seed=1), env_id, ee)


def test_capsule_bounds_never_exceed_coal(env):
    """The cheap bounds the proof stands on are lower bounds of the exact clearance."""
    collision, kin = env.safety.collision, env.kinematics
    gripper = kin.robot.gripper
    rng = np.random.default_rng(3)
    for _ in range(300):
        collision.pose(rng.uniform(kin.arm_lower, kin.arm_upper), rng.uniform(gripper.low, gripper.high))
        assert np.all(collision.bounds() <= collision.all_exact() + 1e-9)


def test_capsule_halving_proves_only_pairs_that_keep_their_threshold(env):
    """The compiled capsule pass over a motion: every pair it calls proven keeps its threshold at 129 evenly
    spaced poses of the motion, by coal's exact clearance (the shapes, not the capsules); pairs whose ends
    coal already puts inside the threshold are never called proven; and the pass does prove pairs the two
    end bounds alone leave in doubt (it has work to do on these motions)."""
    collision, kin, check = env.safety.collision, env.kinematics, env.safety
    gripper = kin.robot.gripper
    rng = np.random.default_rng(12)
    proven_total = doubted_total = 0
    for _ in range(60):
        q_from = rng.uniform(kin.arm_lower, kin.arm_upper)
        q_to = np.clip(q_from + rng.uniform(-0.3, 0.3, q_from.size), kin.arm_lower, kin.arm_upper)
        value = rng.uniform(gripper.low, gripper.high)
        travel = collision.pair_lever[:, : q_from.size] @ np.abs(q_to - q_from)
        threshold = check.margin
        no_reserve = np.zeros(collision.pair_count)
        collision.pose(q_from, value)
        start = collision.bounds()
        collision.pose(q_to, value)
        end = collision.bounds()
        doubted = np.flatnonzero(start + end - travel < 2 * threshold)
        left = collision.unproven_by_capsules(
            q_from, q_to - q_from, value, doubted, start, end, travel, no_reserve, threshold, 4
        )
        proven = np.setdiff1d(doubted, left)
        proven_total += proven.size
        doubted_total += doubted.size
        if not proven.size:
            continue
        for fraction in np.linspace(0.0, 1.0, 129):
            collision.pose(q_from + fraction * (q_to - q_from), value)
            exact = collision.exact(proven)
            assert np.all(exact >= threshold[proven] - 1e-9), [
                collision.pair_names(int(k)) for k in proven[exact < threshold[proven]]
            ]
    assert proven_total > 0.2 * doubted_total, (proven_total, doubted_total)


def test_compiled_pass_proves_only_pairs_that_keep_their_threshold_while_the_gripper_moves(env):
    """The compiled pass over a motion that moves the gripper too (capsules at the gripper's middle value less its
    reserve; every piece halved 3 times, then a pair's own unproven pieces 3 times more), judged by coal's exact
    clearance on a grid of 17 arm poses of the motion times 5 gripper values of its range: no pair is called proven
    whose threshold lies above its least clearance on the grid (each pair asked at the edge: 0.5 mm above it), and
    with the margins as thresholds the deeper halving proves pairs the first 3 levels leave (the pass has work)."""
    collision, kin, check = env.safety.collision, env.kinematics, env.safety
    gripper = kin.robot.gripper
    arm = len(kin.robot.arm_joints)
    rng = np.random.default_rng(21)
    home = np.asarray(kin.robot.home, float)
    by_deeper = asked = 0
    for trial in range(24):
        # half the motions anywhere, half about home where the random and expert steps spend their time
        q_from = (
            rng.uniform(kin.arm_lower, kin.arm_upper)
            if trial % 2
            else np.clip(home + rng.uniform(-0.8, 0.8, home.size), kin.arm_lower, kin.arm_upper)
        )
        q_to = np.clip(q_from + rng.uniform(-0.5, 0.5, q_from.size), kin.arm_lower, kin.arm_upper)
        g_from, g_to = rng.uniform(gripper.low, gripper.high, 2)
        middle = (g_from + g_to) / 2
        travel = collision.pair_lever[:, :arm] @ np.abs(q_to - q_from)
        reserve = collision.pair_lever[:, arm] * abs(g_to - g_from) / 2
        collision.pose(q_from, middle)
        start = collision.bounds() - reserve
        collision.pose(q_to, middle)
        end = collision.bounds() - reserve
        doubted = np.flatnonzero(start + end - travel < 2 * check.margin)
        left = collision.unproven_by_capsules(
            q_from, q_to - q_from, middle, doubted, start, end, travel, reserve, check.margin, 3, 3
        )
        shallow = collision.unproven_by_capsules(
            q_from, q_to - q_from, middle, doubted, start, end, travel, reserve, check.margin, 3, 0
        )
        by_deeper += np.setdiff1d(shallow, left).size
        # the gripper's reserve is taken at every pose the pass tries, not only at the ends: with ends that keep
        # their margin and a reserve of a metre everywhere between them, no doubted pair is proven
        collision.pose(q_from, middle)
        bare_start = collision.bounds()
        collision.pose(q_to, middle)
        bare_end = collision.bounds()
        huge = np.ones(collision.pair_count)
        doubted_bare = np.flatnonzero(bare_start + bare_end - travel < 2 * check.margin)
        assert np.array_equal(
            np.sort(
                collision.unproven_by_capsules(
                    q_from, q_to - q_from, middle, doubted_bare, bare_start, bare_end, travel, huge, check.margin, 3, 3
                )
            ),
            doubted_bare,
        )
        least = np.full(doubted.size, np.inf)
        for fraction in np.linspace(0.0, 1.0, 17):
            for value in np.linspace(g_from, g_to, 5):
                collision.pose(q_from + fraction * (q_to - q_from), value)
                least = np.minimum(least, collision.exact(doubted))
        # the ends must leave the question open for the pass to be asked it
        edge = np.zeros(collision.pair_count)
        edge[doubted] = least + 0.0005
        asked_pairs = doubted[start[doubted] + end[doubted] - travel[doubted] < 2 * edge[doubted]]
        asked += asked_pairs.size
        called_proven = np.setdiff1d(
            asked_pairs,
            collision.unproven_by_capsules(
                q_from, q_to - q_from, middle, asked_pairs, start, end, travel, reserve, edge, 3, 3
            ),
        )
        assert called_proven.size == 0, [collision.pair_names(int(k)) for k in called_proven]
    assert by_deeper > 0 and asked > 100, (by_deeper, asked)


def test_motion_proof_proves_only_motions_coal_finds_clear(env):
    """The compiled proof of a whole motion (travel, reserve, bounds at both ends, the last end's bounds reused for
    the start, the pass between): every motion it calls proven keeps every pair its margin by coal's exact
    clearance on a grid of 17 arm poses times 5 gripper values; the start and end bounds it reports are below coal's
    clearance at those poses over the gripper's range, reused or measured; and both outcomes occur."""
    from envfactory.geometry.kernels.motion import DOUBT_AT_ENDS, PROVEN

    collision, kin, check = env.safety.collision, env.kinematics, env.safety
    gripper = kin.robot.gripper
    rng = np.random.default_rng(7)
    home = np.asarray(kin.robot.home, float)
    outcomes = set()
    reused = 0
    for trial in range(24):
        q_from = (
            rng.uniform(kin.arm_lower, kin.arm_upper)
            if trial % 3 == 0
            else np.clip(home + rng.uniform(-0.6, 0.6, home.size), kin.arm_lower, kin.arm_upper)
        )
        q_to = np.clip(q_from + rng.uniform(-0.3, 0.3, q_from.size), kin.arm_lower, kin.arm_upper)
        g_from, g_to = rng.uniform(gripper.low, gripper.high, 2)
        last = None
        if trial % 2:  # a last end 1-2 mm away, measured over a narrower gripper range: its bounds stand in
            near = np.clip(q_from + rng.uniform(-5e-4, 5e-4, q_from.size), kin.arm_lower, kin.arm_upper)
            collision.pose(near, (g_from + g_to) / 2)
            last = (near, collision.bounds(), abs(g_to - g_from) / 2)
        proof = collision.motion_proof(
            q_from, q_to - q_from, g_from, g_to, check.margin, last, check.REUSE_WITHIN, 3, 3
        )
        outcomes.add(proof.outcome)
        # how far each pair can close: each coordinate's lever times its change (the levers' own test is Bullet's)
        assert np.allclose(proof.travel, collision.pair_lever[:, :-1] @ np.abs(q_to - q_from), rtol=1e-12, atol=0)
        assert np.allclose(proof.reserve, collision.pair_lever[:, -1] * abs(g_to - g_from) / 2, rtol=1e-12, atol=0)
        if last is not None:
            moved = collision.pair_lever[:, :-1] @ np.abs(q_from - last[0]) + collision.pair_lever[:, -1] * last[2]
            reused += bool(moved.max() <= check.REUSE_WITHIN)
        grid = []
        for fraction in np.linspace(0.0, 1.0, 17):
            for value in np.linspace(g_from, g_to, 5):
                collision.pose(q_from + fraction * (q_to - q_from), value)
                grid.append(collision.all_exact())
        grid = np.array(grid).reshape(17, 5, -1)
        assert (proof.start_bound <= grid[0].min(axis=0) + 1e-9).all(), trial
        assert (proof.end_bound <= grid[-1].min(axis=0) + 1e-9).all(), trial
        if proof.outcome == PROVEN:
            short = np.flatnonzero(grid.min(axis=(0, 1)) < check.margin - 1e-9)
            assert short.size == 0, [collision.pair_names(int(k)) for k in short]
        else:
            assert proof.outcome == DOUBT_AT_ENDS or proof.unproven.size > 0
    assert PROVEN in outcomes and len(outcomes) > 1, outcomes
    assert reused > 0


def test_a_non_finite_reading_is_refused(env):
    """A reading with a NaN or an infinity in it (a blown-up simulation, a corrupt message) leaves every bound NaN,
    and a NaN compares false with every threshold: the check must refuse it, not call it clear."""
    check, kin = env.safety, env.kinematics
    home = np.asarray(kin.robot.home, float)
    assert check.check(home, home).accepted
    for bad in (np.nan, np.inf):
        reading = home.copy()
        reading[1] = bad
        verdict = check.check(reading, home)
        assert not verdict.accepted and "non-finite" in verdict.reason
        assert not check.check(home, home, gripper_now=bad).accepted
        assert not check.path_is_clear(reading, home).accepted


def test_levers_bound_every_shape_move_by_bullet(env):
    """No point of any link moves farther than lever · |Δ coordinates|: judged on Bullet's link AABBs,
    whose corners move with the links' collision shapes."""
    import pybullet as p

    collision, kin = env.safety.collision, env.kinematics
    judge = BulletJudge(env, 0.0)
    link_of = {}
    for index in range(p.getNumJoints(judge.body, physicsClientId=judge.client)):
        link_of[p.getJointInfo(judge.body, index, physicsClientId=judge.client)[12].decode()] = index
    gripper = kin.robot.gripper
    rng = np.random.default_rng(4)
    try:
        for _ in range(100):
            q = rng.uniform(kin.arm_lower, kin.arm_upper)
            g = rng.uniform(gripper.low, gripper.high)
            dq = rng.uniform(-0.02, 0.02, q.size)
            dg = rng.uniform(-0.1, 0.1) * (gripper.high - gripper.low)
            q2, g2 = np.clip(q + dq, kin.arm_lower, kin.arm_upper), np.clip(g + dg, gripper.low, gripper.high)
            change = np.append(np.abs(q2 - q), abs(g2 - g))
            for index, shape in enumerate(collision.shapes):
                if shape.joint == 0:
                    continue
                link = link_of[shape.link]
                judge.pose(q, g)
                before = np.array(p.getAABB(judge.body, link, physicsClientId=judge.client))
                judge.pose(q2, g2)
                after = np.array(p.getAABB(judge.body, link, physicsClientId=judge.client))
                # an AABB face moves no farther than the farthest-moving point of the link's shapes (Bullet's
                # AABB is the link's, over all its shapes)
                bound = max(
                    collision.lever[other] @ change
                    for other, same in enumerate(collision.shapes)
                    if same.link == shape.link
                )
                assert np.abs(after - before).max() <= bound + 2e-3, shape.link
    finally:
        judge.close()


def test_ur5e_straight_down_stops_above_the_table():
    """Straight down at full scale in EE mode, twice, from the seed-0 start: the fingers keep the margin."""
    environment = make("UR5eReacherSim-v0", ee_action_type=True)
    judge = BulletJudge(environment, 0.05)
    try:
        environment.reset(seed=0)
        for _ in range(4):
            _, _, _, _, info = environment.step(np.array([0.0, 0.0, -1.5], dtype=np.float32))
            lowest, what = judge.simulated()
            assert lowest >= environment.blueprint.spec.env.safety.surface_margin, what
        assert info["action_rejected"] == 1.0, "the last steps would reach the table: refused"
    finally:
        judge.close()
        environment.close()


def test_vx300s_repeated_fold_is_refused_before_the_table():
    environment = make("VX300SReacherSim-v0")
    judge = BulletJudge(environment, 0.05)
    try:
        environment.reset(seed=0)
        action = np.array([0.0, 1.26, 1.61, 0.0, 0.0, 3.14], dtype=np.float32)
        refused = 0
        for _ in range(10):
            before = environment.state.q_arm.copy()
            command = environment.actions.translate(action, environment.state)
            _, _, _, _, info = environment.step(action)
            refused += int(info["action_rejected"])
            if not info["action_rejected"]:
                lowest, what = judge.commanded(
                    before, command.q_arm, environment.state.gripper, environment.state.gripper
                )
                assert lowest >= environment.blueprint.spec.env.safety.surface_margin, what
        assert refused > 0
    finally:
        judge.close()
        environment.close()


def test_inside_the_margin_only_a_way_out_is_accepted():
    environment = make("UR5eReacherSim-v0")
    safety = environment.safety
    try:
        environment.reset(seed=0)
        # lower the arm from home until the fingers are inside the margin, by joint-space search
        q = environment.home.copy()
        lift = np.array([0.0, 0.02, 0.0, 0.0, 0.0, 0.0])  # shoulder lift down brings the gripper down
        for _ in range(200):
            if not safety.pose_is_clear(q):
                break
            q = q + lift
        assert not safety.pose_is_clear(q), "found no pose inside the margin"
        safety.forget()
        assert not safety.check(q, q + lift).accepted, "deeper must be refused"
        assert safety.check(q, q - 3 * lift).accepted, "the way out must be accepted"
        assert not safety.check(q, q).accepted, "standing still inside the margin does not move it away"
    finally:
        environment.close()


def test_max_joint_delta_rejects_large_jumps(env):
    target = env.home.copy()
    target[0] += 0.6
    verdict = env.safety.check(env.home, target)
    assert not verdict.accepted and "max_joint_delta" in verdict.reason


@pytest.mark.parametrize("bad", [np.zeros((7, 1)), np.zeros(6), np.array(["a"] * 7)])
def test_malformed_actions_are_refused_before_anything_moves(env, bad):
    env.reset(seed=0)
    before = env.backend.read_joints().position.copy()
    with pytest.raises(ValueError, match="action space"):
        env.step(bad)
    assert np.array_equal(env.backend.read_joints().position, before)


def test_a_stale_pair_list_is_refused(env, tmp_path):
    collision = env.safety.collision
    margin = env.blueprint.spec.env.safety.surface_margin
    path = tmp_path / "pairs.yaml"
    write_pairs(path, "robot", {"fingerprint": "0" * 16, "margin": margin, "samples": 1, "seed": 0, "skipped": []})
    with pytest.raises(StalePairs, match="stale"):
        read_pairs(path, collision, margin)
    wide = {"fingerprint": fingerprint(collision, 0.05), "margin": 0.05, "samples": 1, "seed": 0, "skipped": []}
    write_pairs(path, "robot", {**wide, "checksum": checksum(wide)})
    with pytest.raises(StalePairs, match="above the spec"):
        read_pairs(path, collision, margin)


def test_the_gripper_moving_on_the_way_counts():
    """The same arm path is clear with the gripper open and not when it closes on the way: closing
    brings the Robotiq fingertips down towards the table."""
    environment = make("UR5ePnPSim-v0")
    safety = environment.safety
    try:
        environment.reset(seed=0)
        pads = [
            k
            for k in range(safety.collision.pair_count)
            if safety.collision.pair_names(k) == ("robotiq_left_inner_finger_pad", "table top")
        ]
        q = environment.home.copy()
        lower = np.array([0.0, 0.01, 0.0, 0.0, 0.0, 0.0])  # shoulder lift: the gripper goes down
        while safety.clearances(q, 0.0)[pads].min() > safety.margin[pads].max() + 0.008:
            q = q + lower
        assert safety.path_is_clear(q, q, 0.0, 0.0).accepted
        assert not safety.path_is_clear(q, q, 0.0, 0.8).accepted
    finally:
        environment.close()


def test_finger_sweep_bounds_stay_below_bullet(env):
    """The tabulated finger sweep's bound over a gripper range never exceeds PyBullet's distance between a
    finger link and an obstacle or an arm link, at gripper values across that range, off the tabulated
    values too (less the engines' disagreement); and near contact it stays within a few millimetres of
    it, so it spares coal."""
    import pybullet as p

    collision, kin = env.safety.collision, env.kinematics
    sweep, gripper = collision.gripper_sweep, kin.robot.gripper
    judge = BulletJudge(env, 0.0)
    links = {
        p.getJointInfo(judge.body, j, physicsClientId=judge.client)[12].decode(): j
        for j in range(p.getNumJoints(judge.body, physicsClientId=judge.client))
    }
    links[p.getBodyInfo(judge.body, physicsClientId=judge.client)[0].decode()] = -1
    obstacle_body = dict(zip((o.name for o in collision.obstacles), judge.obstacles))
    every = np.arange(collision.pair_count)
    measured = every[sweep.sweepable(every)]
    # Bullet measures a link against a link over all their shapes: judge the link pairs whose every
    # shape pair the sweep measures, by the least of their bounds
    shapes_of = {}
    for index, shape in enumerate(collision.shapes):
        shapes_of.setdefault(shape.link, []).append(index)
    by_names = {}
    for pair in measured:
        by_names.setdefault(collision.pair_names(pair), []).append(pair)
    groups = {
        names: members
        for names, members in by_names.items()
        if names[1] in obstacle_body or len(members) == len(shapes_of[names[0]]) * len(shapes_of[names[1]])
    }
    names = list(groups)
    scene = np.array([second in obstacle_body for _, second in names])
    assert scene.sum() >= 2 * len(collision.obstacles) and (~scene).sum() >= 2  # both kinds are measured

    def bullet_distance(first, second):
        if second in obstacle_body:
            points = p.getClosestPoints(
                judge.body, obstacle_body[second], 0.1, linkIndexA=links[first], physicsClientId=judge.client
            )
        else:
            points = p.getClosestPoints(
                judge.body,
                judge.body,
                0.1,
                linkIndexA=links[first],
                linkIndexB=links[second],
                physicsClientId=judge.client,
            )
        return min([point[8] for point in points] or [np.inf])

    rng = np.random.default_rng(12)
    close_gaps = {True: [], False: []}
    try:
        for trial in range(400):
            q = rng.uniform(kin.arm_lower, kin.arm_upper)
            low, high = np.sort(rng.uniform(gripper.low, gripper.high, 2))
            collision.pose(q, (low + high) / 2)
            clearance = dict(zip(measured, sweep.clearances(measured, low, high)))
            bound = np.array([min(clearance[pair] for pair in groups[key]) for key in names])
            if bound.min() > 0.05 and trial % 10:  # most far poses only cost time; judge one in ten
                continue
            bullet = np.full(len(names), np.inf)
            for value in np.linspace(low, high, 9):
                judge.pose(q, value)
                bullet = np.minimum(bullet, [bullet_distance(*key) for key in names])
            bad = bound > bullet + 2 * env.safety.SHAPE_TOLERANCE
            assert not bad.any(), [(key, b, c) for key, b, c, wrong in zip(names, bound, bullet, bad) if wrong]
            for kind in (True, False):
                near = (bullet < 0.05) & (scene == kind)
                close_gaps[kind] += list((bullet - bound)[near])
    finally:
        judge.close()
    obstacles, links_ = close_gaps[True], close_gaps[False]
    assert len(obstacles) >= 20 and np.median(obstacles) < 0.005, (len(obstacles), np.median(obstacles))
    assert len(links_) >= 20 and np.median(links_) < 0.02, (len(links_), np.median(links_))


def test_compiled_frames_match_pinocchio(env):
    """The compiled forward kinematics behind the capsule bounds agrees with Pinocchio's at random poses."""
    import pinocchio as pin

    collision, kin = env.safety.collision, env.kinematics
    gripper = kin.robot.gripper
    data = kin.model.createData()
    rng = np.random.default_rng(5)
    for _ in range(200):
        q_arm, value = rng.uniform(kin.arm_lower, kin.arm_upper), rng.uniform(gripper.low, gripper.high)
        collision.pose(q_arm, value)
        collision.bounds()
        pin.forwardKinematics(kin.model, data, kin.full_q(q_arm, value))
        for joint in range(1, kin.model.njoints):
            assert np.allclose(collision._frames[joint], data.oMi[joint].homogeneous[:3], atol=1e-12)


def test_pairs_proven_apart_stay_apart_by_bullet(env):
    """Every self pair the generated list skips as proven apart keeps, by PyBullet's distance queries over
    random configurations, the clearance its grid proof claims (less the engines' disagreement)."""
    import re

    import pybullet as p

    judge = BulletJudge(env, margin=0.2)
    links = {
        info[12].decode(): info[0]
        for info in (
            p.getJointInfo(judge.body, j, physicsClientId=judge.client)
            for j in range(p.getNumJoints(judge.body, physicsClientId=judge.client))
        )
    }
    links[p.getBodyInfo(judge.body, physicsClientId=judge.client)[0].decode()] = -1
    shape_link = {shape.name: shape.link for shape in env.safety.collision.shapes}
    claims = {
        frozenset(key): float(re.search(r"at least ([\d.]+) mm", why).group(1)) / 1000
        for key, why in env.safety.collision.ignored.items()
        if "grid proof" in why
    }
    # Bullet measures link against link, over all of a link's shapes: judge the link pairs whose every
    # shape pair is proven apart, against the least of their claims
    shapes_of = {}
    for shape in env.safety.collision.shapes:
        shapes_of.setdefault(shape.link, []).append(shape.name)
    link_pairs = {tuple(sorted(shape_link[name] for name in key)) for key in claims}
    proven = []
    for a, b in sorted(link_pairs):
        keys = [frozenset((x, y)) for x in shapes_of[a] for y in shapes_of[b]]
        if all(key in claims for key in keys):
            proven.append((a, b, min(claims[key] for key in keys)))
    assert proven, "the shipped robots have pairs proven apart"
    kin, gripper = env.kinematics, env.kinematics.robot.gripper
    rng = np.random.default_rng(11)
    lowest = {(a, b): np.inf for a, b, _ in proven}
    try:
        for _ in range(400):
            judge.pose(rng.uniform(kin.arm_lower, kin.arm_upper), rng.uniform(gripper.low, gripper.high))
            for a, b, _ in proven:
                for point in p.getClosestPoints(
                    judge.body, judge.body, 0.2, linkIndexA=links[a], linkIndexB=links[b], physicsClientId=judge.client
                ):
                    lowest[a, b] = min(lowest[a, b], point[8])
    finally:
        judge.close()
    for a, b, claimed in proven:
        assert lowest[a, b] >= claimed - 2 * env.safety.SHAPE_TOLERANCE, (a, b, lowest[a, b], claimed)


def test_a_sphere_round_the_first_joint_leaves_it_out_of_the_pair_lever():
    """The UR5e base sphere sits on the shoulder-pan axis: turning the pan cannot change its distance to any
    link, so the pairs it is in carry no pan lever. Judged by Bullet: a sphere body where the check's sphere
    is, against the arm's links, over large random motions (the pan swinging up to a radian)."""
    import pybullet as p

    from envfactory.envs import RobotEnv

    env = RobotEnv(envfactory.blueprint("UR5eReacherSim-v0"))
    collision, kin = env.safety.collision, env.kinematics
    sphere = next(i for i, s in enumerate(collision.shapes) if s.name == "base_link_inertia_0")
    geometry = collision.geometry.geometryObjects[sphere]
    scene = len(collision.scene_shape)
    pairs = [(k, int(collision.self_b[k])) for k in range(len(collision.self_a)) if collision.self_a[k] == sphere]
    assert pairs and all(collision.pair_lever[scene + k][0] == 0.0 for k, _ in pairs)  # no pan lever
    judge = BulletJudge(env, 0.0)
    centre = np.asarray(env.blueprint.spec.robot.mount) + geometry.placement.translation
    ball = p.createMultiBody(
        0,
        p.createCollisionShape(p.GEOM_SPHERE, radius=geometry.geometry.radius, physicsClientId=judge.client),
        basePosition=list(centre),
        physicsClientId=judge.client,
    )
    link_of = {
        p.getJointInfo(judge.body, j, physicsClientId=judge.client)[12].decode(): j
        for j in range(p.getNumJoints(judge.body, physicsClientId=judge.client))
    }

    def distance(link):
        points = p.getClosestPoints(ball, judge.body, 10.0, linkIndexB=link_of[link], physicsClientId=judge.client)
        return min(point[8] for point in points)

    rng = np.random.default_rng(3)
    moved = 0
    try:
        for _ in range(60):
            q = rng.uniform(kin.arm_lower, kin.arm_upper)
            q2 = q.copy()
            q2[0] = np.clip(q[0] + rng.uniform(-1.0, 1.0), kin.arm_lower[0], kin.arm_upper[0])  # the pan
            q2[1:] = np.clip(q[1:] + rng.uniform(-0.02, 0.02, q.size - 1), kin.arm_lower[1:], kin.arm_upper[1:])
            change = np.append(np.abs(q2 - q), 0.0)
            for k, other in pairs:
                link = collision.shapes[other].link
                judge.pose(q, 0.0)
                before = distance(link)
                judge.pose(q2, 0.0)
                after = distance(link)
                bound = collision.pair_lever[scene + k] @ change
                assert abs(after - before) <= bound + 2e-3, (link, before, after, bound)
                moved += bound < 0.2 * abs(q2[0] - q[0])  # the pan alone would have allowed far more
    finally:
        judge.close()
    assert moved > 100
