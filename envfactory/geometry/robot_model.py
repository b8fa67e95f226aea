"""A robot in its scene as geometry, built once per process and shared.

Loading the URDF into Pinocchio and building the collision model (shapes, levers,
compiled tables, the gripper sweep, the generated pair list) is the slow part of
making an env: 0.1-0.4 s a robot. It depends only on the robot's shape, the scene
and the safety settings, so it is built once for each distinct set of those and
every env, check and tool of the process shares it. What a user mutates (Pinocchio's
data, the posed frames, the safety check's memory of the last motion) lives in a
measuring copy each user takes for itself.
"""

from __future__ import annotations

import hashlib
from collections import Counter, OrderedDict
from dataclasses import dataclass
from pathlib import Path

from envfactory.geometry.collision import CollisionModel
from envfactory.geometry.collision_pairs import DEFAULT_SAMPLES, pairs_file, read_pairs, sample_pairs, write_pairs
from envfactory.geometry.fixtures import FixtureModel, fixture_models
from envfactory.geometry.frames import TaskFrame
from envfactory.geometry.kinematics import Kinematics
from envfactory.geometry.obstacles import guarded_obstacles, scene_obstacles
from envfactory.geometry.safety import SafetyCheck
from envfactory.geometry.urdf_assembly import assemble
from envfactory.schema.models import ComposedSpec
from envfactory.schema.settings import SafetySettings

# The robot fields the kinematic chain is built from; the others (home, bounds, topics, labels)
# leave a built chain valid.
KINEMATIC_FIELDS = {"name", "model", "mount", "mount_rpy", "task_frame", "arm_joints", "ee_frame", "gripper"}
# ... and those the collision model adds: the pedestal is an obstacle, padding and the pair list are shapes'.
COLLISION_FIELDS = KINEMATIC_FIELDS | {"pedestal", "safety"}
KEEP = 16  # distinct robots-in-scenes kept per process; a sweep over many variants evicts the oldest

builds: Counter = Counter()  # how many chains and collision models this process built (tests count them)


@dataclass(frozen=True)
class RobotGeometry:
    """The shared, never-mutated model of one robot in one scene."""

    urdf: Path
    kinematics: Kinematics
    collision: CollisionModel
    fixtures: dict[str, FixtureModel]  # the task's fixtures in the world; their boxes are obstacles of `collision`

    def safety_check(self, settings: SafetySettings) -> SafetyCheck:
        """A safety check of the caller's own (it remembers its last motion) over its own measuring copy."""
        return SafetyCheck(self.collision.measuring_copy(), settings)


class _Kept(OrderedDict):
    """A small least-recently-used table."""

    def get_or_build(self, key: str, build):
        if key in self:
            self.move_to_end(key)
            return self[key]
        value = self[key] = build()
        while len(self) > KEEP:
            self.popitem(last=False)
        return value


_chains = _Kept()
_geometries = _Kept()


def _digest(*parts: str) -> str:
    return hashlib.sha256("\0".join(parts).encode()).hexdigest()


def robot_chain(spec: ComposedSpec, asset_root: Path) -> tuple[Path, Kinematics]:
    """The assembled URDF and the shared kinematic chain of a spec's robot (AssemblyError, or Pinocchio's
    own error, when the model does not load)."""
    robot = spec.robot
    key = _digest(robot.model_dump_json(include=KINEMATIC_FIELDS), str(asset_root))

    def build():
        urdf = assemble(robot.model, asset_root, robot.name)
        builds["kinematics"] += 1
        return urdf, Kinematics(urdf, robot, TaskFrame.of(robot))

    return _chains.get_or_build(key, build)


def robot_geometry(spec: ComposedSpec, asset_root: Path, fixture_folders=()) -> RobotGeometry:
    """The shared geometry of a spec's robot in its scene, with the task's fixtures (`fixture_folders`: (name,
    folder its URDF path is relative to) pairs); StalePairs when its generated pair list no longer matches it.
    The key covers the pair list's text, so a regenerated or edited list is read again."""
    pairs = pairs_file(spec, asset_root)
    pairs_text = pairs.read_text() if pairs is not None and pairs.is_file() else ""
    key = _digest(
        spec.robot.model_dump_json(include=COLLISION_FIELDS),
        spec.scene.model_dump_json(),
        spec.task.model_dump_json(include={"fixtures"}),
        str(tuple(fixture_folders)),
        spec.env.safety.model_dump_json(),
        str(asset_root),
        pairs_text,
    )

    def build():
        urdf, kinematics = robot_chain(spec, asset_root)
        fixtures = fixture_models(spec, dict(fixture_folders))
        obstacles = guarded_obstacles(spec) + [o for fixture in fixtures.values() for o in fixture.obstacles()]
        collision = CollisionModel(kinematics, obstacles, dict(spec.robot.safety.padding))
        if pairs is not None:
            collision.set_ignored_pairs(read_pairs(pairs, collision, spec.env.safety.surface_margin))
        builds["collision"] += 1
        return RobotGeometry(urdf, kinematics, collision, fixtures)

    return _geometries.get_or_build(key, build)


def regenerate_pairs(spec: ComposedSpec, asset_root: Path, samples: int = DEFAULT_SAMPLES, seed: int = 0) -> Path:
    """Sample the robot's self pairs again and write them where its YAML points."""
    path = pairs_file(spec, asset_root)
    if path is None:
        raise ValueError(f"robot {spec.robot.name!r} names no safety.collision_pairs file to write")
    _, kinematics = robot_chain(spec, asset_root)
    collision = CollisionModel(kinematics.measuring_copy(), scene_obstacles(spec), dict(spec.robot.safety.padding))
    write_pairs(path, spec.robot.name, sample_pairs(collision, spec.env.safety.surface_margin, samples, seed))
    return path
