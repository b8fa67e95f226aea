"""The Ned2 folded into itself, judged by Niryo's own meshes (reference data, not in the repository).

The Ned2's forearm turns a few millimetres from its upper arm at the elbow in every pose, and near the
lower limit of joint_3 Niryo's meshes of the two cross: the arm folds into itself inside its joint limits.
The safety check measures those links against margins of their own, down to contact, instead of skipping
them. Here the arm is driven towards such folds, found and judged with the maker's meshes posed by the
maker's URDF, never with the check's own shapes: every fold must be refused before the meshes touch, and
the home pose and ordinary motions must still pass (a check that refused everything would pass the first
test). The generator's side: a pair too coarse to tell a pose from a fold stops it, and a list written
before pairs had margins of their own (one that skips pairs for sitting always within the margin) is
refused.
"""

from __future__ import annotations

import re

import gymnasium as gym
import numpy as np
import pytest
import yaml

from devkit.oracles.maker_models import MakerMeshes, models_folder
from envfactory.geometry.collision import CollisionModel
from envfactory.geometry.collision_pairs import (
    StalePairs,
    UncheckablePairs,
    checksum,
    read_pairs,
    sample_pairs,
    write_pairs,
)
from envfactory.geometry.frames import TaskFrame
from envfactory.geometry.kinematics import Kinematics
from envfactory.geometry.safety import SafetyCheck
from envfactory.schema.folders import builtin_root

ENV_ID = "NED2ReacherSim-v0"
PAIRS = builtin_root() / "robots" / "assets" / "ned2.collision.yaml"
# The arm's bodies in chain order (the hand, the gripper and its jaws move as one against the arm). A fold is
# judged on every pair of them not joined by one joint: folding the elbow shut brings the forearm's end to the
# shoulder as well as the forearm onto the arm.
CHAIN = [
    ["base_link"],
    ["shoulder_link"],
    ["arm_link"],
    ["elbow_link"],
    ["forearm_link"],
    ["wrist_link"],
    ["hand_link", "base_gripper_1", "mors_1", "mors_2"],
]
JUDGED = [(a, b) for i, group in enumerate(CHAIN) for later in CHAIN[i + 2 :] for a in group for b in later]
ELBOW = ("arm_link", "forearm_link")
STEP = 0.1  # rad of joint_3 per commanded motion, well inside max_joint_delta
FOLDS = 12
APART = 0.001  # m: an accepted motion keeps the maker's meshes at least this far apart


def _maker_urdf():
    folder = models_folder()
    return None if folder is None or not (folder / "ned2" / "ned2.urdf").is_file() else folder / "ned2" / "ned2.urdf"


needs_maker = pytest.mark.skipif(
    _maker_urdf() is None,
    reason="Niryo's model is absent: set ENVFACTORY_ROBOT_MODELS or put it at ../shared/robot-models/ned2",
)


@pytest.fixture(scope="module")
def maker():
    return MakerMeshes(_maker_urdf())


@pytest.fixture(scope="module")
def env():
    environment = gym.make(ENV_ID)
    yield environment.unwrapped
    environment.close()


def _values(env, q_arm, gripper):
    robot = env.kinematics.robot
    values = {joint.name: float(value) for joint, value in zip(robot.arm_joints, q_arm)}
    values[robot.gripper.joint] = gripper
    values.update({name: gain * gripper for name, gain in robot.gripper.mimic.items()})
    return values


def _lowest(maker, env, q_from, q_to, gripper, pairs=JUDGED, samples=6):
    """The maker's meshes' least gap per pair of bodies along a straight joint motion."""
    lowest = {pair: np.inf for pair in pairs}
    for fraction in np.linspace(0.0, 1.0, samples + 1):
        placed = maker.pose(_values(env, q_from + fraction * (q_to - q_from), gripper))
        for pair in pairs:
            lowest[pair] = min(lowest[pair], maker.distance(placed, *pair))
    return lowest


def _folds(maker, env, gripper, count=FOLDS, seed=0):
    """Poses where the maker's meshes of the arm and the forearm touch: joint_3 near its lower limit, the
    forearm turned anyhow, the rest of the arm anyhow but up, with the elbow open clear for the check (where
    the drive starts)."""
    kin, safety = env.kinematics, env.safety
    rng = np.random.default_rng(seed)
    folds, tried = [], 0
    while len(folds) < count:
        tried += 1
        assert tried < 50 * count, "Niryo's meshes no longer fold into each other near joint_3's lower limit"
        q = np.array(
            [
                rng.uniform(-1.0, 1.0),
                rng.uniform(-0.3, 0.6),
                rng.uniform(kin.arm_lower[2], kin.arm_lower[2] + 0.06),
                rng.uniform(kin.arm_lower[3], kin.arm_upper[3]),
                rng.uniform(-1.9, 1.9),
                rng.uniform(-1.0, 1.0),
            ]
        )
        if maker.distance(maker.pose(_values(env, q, gripper)), *ELBOW) == 0.0 and safety.pose_is_clear(
            _opened(q), gripper
        ):
            folds.append(q)
    return folds


def _opened(q):
    """The same pose with the elbow open: the maker's meshes apart by their design gap alone."""
    start = q.copy()
    start[2] = -0.4
    return start


@needs_maker
def test_every_fold_of_the_forearm_onto_the_arm_is_refused(env, maker):
    """At each fold the arm's and the forearm's own pairs are inside their margins (the check refuses it on
    their account, whatever else is near). Driven there from an open elbow, joint_3 down a step at a time,
    every motion the check accepts keeps the maker's meshes of every two bodies not joined by one joint
    apart all the way, and the check refuses before the fold is reached."""
    safety, gripper = env.safety, env.kinematics.robot.gripper.open
    elbow = [
        pair for pair in range(safety.collision.pair_count) if sorted(safety.collision.pair_names(pair)) == list(ELBOW)
    ]
    assert elbow, "the check measures no pair of the arm and the forearm"
    for fold in _folds(maker, env, gripper):
        inside = safety.clearances(fold, gripper)[elbow] - safety.margin[elbow]
        assert inside.min() < 0.0, f"the fold {np.round(fold, 3)} keeps every arm-forearm pair's margin: {inside}"
        now = _opened(fold)
        safety.forget()
        while True:
            target = now.copy()
            target[2] = max(fold[2], now[2] - STEP)
            verdict = safety.check(now, target, gripper, gripper)
            if not verdict.accepted:
                break
            lowest = _lowest(maker, env, now, target, gripper)
            closest = min(lowest, key=lowest.get)
            assert lowest[closest] > APART, (np.round(now, 3), np.round(target, 3), closest, lowest[closest])
            assert not np.array_equal(target, fold), f"the fold {np.round(fold, 3)} was accepted"
            now = target


@needs_maker
def test_home_and_ordinary_motions_are_still_accepted(env, maker):
    """The home pose, random moves about it, and the elbow bent as far as reaching near the base needs (the
    goal box's poses, joint_3 near -0.9) with the forearm square to the arm: the maker's meshes stay well
    apart in all of them, and the check accepts them."""
    safety, gripper = env.safety, env.kinematics.robot.gripper.open
    home = np.asarray(env.blueprint.spec.robot.home, float)
    safety.forget()
    assert safety.pose_is_clear(home, gripper)
    assert safety.check(home, home, gripper, gripper).accepted
    rng = np.random.default_rng(1)
    for _ in range(20):
        target = home + rng.uniform(-0.4, 0.4, home.size)
        safety.forget()
        verdict = safety.check(home, target, gripper, gripper)
        assert verdict.accepted, (np.round(target, 3), verdict.reason)
        assert min(_lowest(maker, env, home, target, gripper).values()) > APART
    bend = np.array([0.0, 0.5, -0.4, 0.0, -0.7, 0.0])
    safety.forget()
    for _ in range(5):  # joint_3 from -0.4 to -0.9 in steps, each judged from where the last one ended
        target = bend + np.array([0.0, 0.0, -STEP, 0.0, 0.0, 0.0])
        verdict = safety.check(bend, target, gripper, gripper)
        assert verdict.accepted, (np.round(target, 3), verdict.reason)
        assert min(_lowest(maker, env, bend, target, gripper).values()) > APART
        bend = target


def test_the_shipped_list_skips_only_what_is_proven_and_measures_the_elbow_against_own_margins(env):
    """No pair of the Ned2 is skipped for sitting within the margin; the pairs round the elbow are measured,
    each against the margin the list gives it (plus the engines' disagreement), not the surface margin."""
    data = yaml.safe_load(PAIRS.read_text())
    reasons = {why if "(grid proof)" not in why else "grid proof" for *_, why in data["skipped"]}
    assert reasons <= {"rigidly joined", "adjacent", "gripper mechanism", "grid proof"}, reasons
    own = {frozenset(entry[:2]): entry[2] for entry in data.get("pair_margins", [])}
    collision, safety = env.safety.collision, env.safety
    shape_link = {shape.name: shape.link for shape in collision.shapes}
    assert {frozenset(shape_link[name] for name in key) for key in own} == {frozenset(("arm_link", "forearm_link"))}
    scene = len(collision.scene_shape)
    tolerance = SafetyCheck.ROUNDING + 2 * SafetyCheck.SHAPE_TOLERANCE
    for offset, (a, b) in enumerate(zip(collision.self_a, collision.self_b)):
        key = frozenset((collision.shapes[a].name, collision.shapes[b].name))
        expected = own.get(key, env.blueprint.spec.env.safety.surface_margin) + tolerance
        assert safety.margin[scene + offset] == pytest.approx(expected), key
    assert set(own) <= {
        frozenset((collision.shapes[a].name, collision.shapes[b].name))
        for a, b in zip(collision.self_a, collision.self_b)
    }, "a pair with a margin is not measured"


def test_a_pair_too_coarse_to_tell_a_pose_from_a_fold_stops_the_generator(env, tmp_path):
    """The hand's shape grown to touch the forearm's fork in some poses and stay within the margin in
    all: the generator names the pair and asks for tighter shapes instead of writing a list."""
    urdf = env.kinematics.urdf_path.read_text()
    coarse, count = re.subn(
        r'(<link name="hand_link">.*?<cylinder radius=")[0-9.]+', r"\g<1>0.019", urdf, count=1, flags=re.S
    )
    assert count == 1
    path = tmp_path / "ned2_coarse.urdf"
    path.write_text(coarse)
    robot = env.kinematics.robot
    collision = CollisionModel(Kinematics(path, robot, TaskFrame.of(robot)), [])
    with pytest.raises(UncheckablePairs) as caught:
        sample_pairs(collision, env.blueprint.spec.env.safety.surface_margin, samples=300)
    message = str(caught.value)
    assert "hand_link_0" in message and "forearm_link" in message
    assert "Refine their collision shapes" in message and "envfactory collision-pairs ned2" in message


def test_a_list_that_skips_pairs_always_within_the_margin_is_refused(env, tmp_path):
    """A list written before pairs had margins of their own passes its checksum; its reasons give it away.
    An own margin raised past the list's margin is refused too, and a hand-edited one by the checksum."""
    collision = env.safety.collision
    margin = env.blueprint.spec.env.safety.surface_margin
    data = yaml.safe_load(PAIRS.read_text())
    first, second, _ = data["pair_margins"][0]
    path = tmp_path / "pairs.yaml"

    def write(changed):
        body = {key: value for key, value in changed.items() if key != "checksum"}
        write_pairs(path, "ned2", {**body, "checksum": checksum(body)})

    old = {
        **data,
        "pair_margins": data["pair_margins"][1:],
        "skipped": data["skipped"] + [[first, second, "always within the margin"]],
    }
    write(old)
    with pytest.raises(StalePairs, match="neither exempt by structure nor proven apart"):
        read_pairs(path, collision, margin)
    write({**data, "pair_margins": [[first, second, 2 * margin], *data["pair_margins"][1:]]})
    with pytest.raises(StalePairs, match="pair_margins"):
        read_pairs(path, collision, margin)
    edited, count = re.subn(rf"\[{first}, {second}, [0-9.e-]+\]", f"[{first}, {second}, 0.01]", PAIRS.read_text())
    assert count == 1
    path.write_text(edited)
    with pytest.raises(StalePairs, match="checksum"):
        read_pairs(path, collision, margin)
    assert read_pairs(PAIRS, collision, margin).margins  # the shipped list itself reads, with its margins
