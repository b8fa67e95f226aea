"""Every number of the shipped specs pushed to negative, zero, NaN and huge: each mutant is
rejected with file:line, or its acceptance is one of the documented ones below."""

from __future__ import annotations

import math
import re

import pytest

import envfactory
from envfactory.compiler import compile_blueprint
from envfactory.schema.compose import composed_config, validate_config
from envfactory.schema.errors import SpecError
from envfactory.schema.tree import leaves

# (family, what to mutate): both robots through their pick-and-place families; the reach family for its
# task, scene and settings (its robot is the UR5e already covered)
FAMILIES = {"ur5e_pnp": "", "vx300s_pnp": "", "ur5e_reach": "robot."}
MUTATIONS = {"negative": lambda v: -abs(v) - 1.0, "zero": lambda v: 0, "nan": lambda v: math.nan, "huge": lambda v: 1e9}

# Documented acceptances: (path pattern, mutations accepted, why). NaN is never accepted.
ACCEPTED = [
    (r"task\.reward\.\w+\.\w+\.weight", {"negative", "zero", "huge"}, "reward weights are the task's design"),
    (r"env\.safety\.floor_z", {"negative", "zero"}, "the floor may lie anywhere below the table"),
    (r"env\.safety\.table_footprint_margin", {"zero"}, "the table edge itself as the boundary"),
    (r"robot\.arm_joints\.\d+\.delta\.\d", {"negative"}, "a wider delta row, still around zero"),
    (r"robot\.arm_joints\.\d+\.(lower|upper)", {"zero"}, "a joint range ending at 0 that holds home"),
    (r"robot\.ee_bounds\.\d\.\d", {"negative", "zero"}, "observation bounds that still hold the workspace"),
    (r"robot\.gripper\.(grasp_threshold|open)", {"zero"}, "a gripper value within the URDF's range"),
    (r"robot\.gripper\.pads\.\w+_friction", {"zero"}, "frictionless pads are physical"),
    (r"robot\.home\.\d", {"negative", "zero"}, "a home pose within the limits that clears the table"),
    (
        r"robot\.joint_states\.\d+\.(position|velocity)\.\d",
        {"negative", "zero"},
        "wider observation bounds around the commanded range",
    ),
    (r"robot\.model\.frames\.\w+\.xyz\.\d", {"negative", "zero"}, "where the TCP sits is the robot's design"),
    (r"robot\.mount\.\d", {"negative", "zero"}, "the base placed elsewhere, the goals still within reach"),
    (r"robot\.ros\.static_transforms\.\w+\.xyz\.\d", {"negative", "zero"}, "a ROS frame placement"),
    (r"robot\.top_down_rpy\.\d", {"negative", "zero"}, "an orientation"),
    (r"robot\.safety\.padding\.\w+", {"zero"}, "no padding"),
    (r"scene\.camera\.(eye|target)\.\d", {"negative", "zero"}, "a camera placement"),
    (r"sim\.mujoco\.noslip_iterations", {"zero"}, "MuJoCo without its no-slip pass (a squeezed cube creeps)"),
    (r"scene\.table\.center\.\d", {"negative", "zero"}, "the table moved, boxes still on it"),
    (r"task\.expert\.params\.(grasp_height|height)", {"zero"}, "the expert at the cube's centre height"),
    (r"task\.expert\.params\.grip", {"zero"}, "a grip command within the gripper's range"),
    (r"task\.goal\.box\.\d\.\d", {"zero"}, "a goal box edge at 0 that stays valid"),
    (r"task\.gripper\.at_reset", {"zero"}, "a reset gripper value within range"),
    (
        r"task\.objects\.\w+\.(rgba\.\d|spawn\.offset\.\d|spawn\.position\.\d|friction|spinning_friction)",
        {"zero"},
        "a black, fixed-spawn, frictionless or centred object",
    ),
    (r"workspace\.(min|max)\.\d", {"zero"}, "a workspace edge at 0 that still holds the goals"),
    (
        r"task\.randomization\.events\.\w+\.params\.range\.\d",
        {"zero"},
        "a sampled friction or damping that reaches zero",
    ),
    (r"task\.randomization\.sensing\.\w+\.params\.(std|bias_std|drift_std)", {"zero"}, "no noise of that kind"),
    (r"robot\.sensing\.\w+\.params\.steps", {"zero"}, "a delay measured as under half a step"),
    (
        r"robot\.ros\.setup\.\d+\.request\.\w+",
        {"negative", "zero", "huge"},
        "a setup request's values are the driver's to take or refuse at connect (DriverRefused stops the env)",
    ),
    (
        r"robot\.ros\.driver_config\.\w+",
        {"negative", "zero", "huge"},
        "the driver's own configuration, read by the twin alone, which plays what it says",
    ),
]


def _set(config, dotted, value):
    *parents, leaf = dotted.split(".")
    node = config
    for part in parents:
        node = node[int(part)] if isinstance(node, list) else node[part]
    node[int(leaf) if isinstance(node, list) else leaf] = value


def _documented(path: str, kind: str) -> bool:
    return any(re.fullmatch(pattern, path) and kind in kinds for pattern, kinds, _ in ACCEPTED)


def _family(name):
    return next(
        r for r in envfactory.records().values() if r.family.name == name and r.backend == "sim" and not r.goal_env
    )


@pytest.mark.parametrize("family_name", FAMILIES)
def test_every_numeric_mutation_is_rejected_with_a_line_or_documented(family_name):
    skipped = ("registration", "kwargs", *filter(None, [FAMILIES[family_name]]))
    record = _family(family_name)
    config, _ = composed_config(record.family)
    undocumented, unlocated = [], []
    count = 0
    for path, value in leaves(config):
        if path.startswith(skipped) or isinstance(value, bool) or not isinstance(value, (int, float)):
            continue
        for kind, mutate in MUTATIONS.items():
            mutant, sources = composed_config(record.family)
            _set(mutant, path, mutate(value))
            count += 1
            try:
                loaded = validate_config(mutant, sources, record.family)
                compile_blueprint(loaded, record.env_id, record.backend, record.goal_env)
            except SpecError as error:
                first = error.problems[0]
                if first.file is None or first.line is None:
                    unlocated.append((path, kind, str(first)))
                continue
            if kind == "nan" or not _documented(path, kind):
                undocumented.append((path, kind, value))
    assert count > 100
    assert not unlocated, unlocated
    assert not undocumented, f"accepted without a documented reason: {undocumented}"
