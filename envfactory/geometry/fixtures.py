"""A fixture's URDF (task.fixtures: a cabinet with a drawer) as the safety check and the spec checks see it.

Both engines load the URDF themselves. This reads the same file on its own terms: its collision boxes, placed in
the world where the spec stands the fixture, which of them ride on its one moving joint, and the point its
reading gives (the joint's child link origin). The safety check keeps the arm clear of those boxes; the boxes
that ride on the joint are moved to the joint's reading before each check.

Only boxes, and only axis-aligned ones in the world: the safety check's obstacles are axis-aligned boxes, so a
fixture that would need another shape, or a turn that is not a quarter, is refused rather than approximated.
"""

from __future__ import annotations

import xml.etree.ElementTree as ElementTree
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
import pinocchio as pin

from envfactory.geometry.frames import TaskFrame
from envfactory.geometry.obstacles import Obstacle
from envfactory.schema.errors import suggest
from envfactory.schema.folders import builtin_root

FIXTURE_RGBA = (0.62, 0.48, 0.33, 1.0)


class FixtureError(ValueError):
    """A fixture's URDF cannot be used: what is wrong, and which field of the fixture's spec it concerns."""

    def __init__(self, message: str, field: str = "urdf"):
        super().__init__(message)
        self.field = field


@dataclass(frozen=True)
class FixtureBox:
    link: str
    name: str
    center: np.ndarray  # world, the joint at its lower limit
    half_extents: np.ndarray  # world axes
    moves: bool  # rides on the joint
    touch_depth: float  # how far the gripper's fingers may be commanded into it (0: not touchable), m


@dataclass(frozen=True)
class FixtureModel:
    """One fixture in the world: its boxes and its joint."""

    name: str
    urdf: Path
    joint: str
    lower: float
    upper: float
    travel: np.ndarray  # world displacement of the moving links per unit of joint value
    point: np.ndarray  # world position of the joint's child link origin at the lower limit: the fixture's reading
    rotation: np.ndarray  # the fixture base's orientation in the world
    base: np.ndarray  # the fixture base's origin in the world
    boxes: tuple[FixtureBox, ...]
    friction: float
    damping: float

    @property
    def touch_radius(self) -> float:
        """The radius of the sphere about the reading's point that holds every touchable box: all of the fixture
        the fingers may come into contact with (the safety check keeps the arm's shapes off the rest)."""
        corners = [np.linalg.norm(np.abs(b.center - self.point) + b.half_extents) for b in self.boxes if b.touch_depth]
        return float(max(corners, default=0.0))

    def point_at(self, value: float) -> np.ndarray:
        """The reading's point (world) with the joint at `value`."""
        return self.point + self.travel * (value - self.lower)

    def obstacles(self) -> list[Obstacle]:
        """The boxes as obstacles at the joint's lower limit, the moving ones marked with the fixture's name."""
        return [
            Obstacle(
                f"{self.name}/{box.link}/{box.name}",
                tuple(map(float, box.center)),
                tuple(map(float, box.half_extents)),
                FIXTURE_RGBA,
                fixture=self.name,
                moves=box.moves,
                travel=tuple(map(float, self.travel)) if box.moves else (0.0, 0.0, 0.0),
                touch_depth=box.touch_depth,
            )
            for box in self.boxes
        ]


def fixture_urdf(relative: str, folder: Path | None) -> Path:
    """A fixture's URDF: relative to the folder of the file that names it (a task file's), else to the built-in
    tasks/ folder (a user's task may stand the shipped cabinet); or an absolute path."""
    path = Path(relative)
    if path.is_absolute():
        candidates = [path]
    else:
        candidates = [Path(folder) / path] if folder is not None else []
        candidates.append(builtin_root() / "tasks" / path)
    for candidate in candidates:
        if candidate.is_file():
            return candidate
    raise FixtureError(f"no URDF file {relative!r} (looked in {', '.join(str(c.parent) for c in candidates)})")


def _vector(text: str | None, default=(0.0, 0.0, 0.0)) -> np.ndarray:
    return np.array([float(v) for v in text.split()]) if text else np.array(default, float)


def _origin(element) -> pin.SE3:
    origin = element.find("origin") if element is not None else None
    if origin is None:
        return pin.SE3.Identity()
    rotation = pin.rpy.rpyToMatrix(*_vector(origin.get("rpy")))
    return pin.SE3(rotation, _vector(origin.get("xyz")))


def _axis_aligned(rotation: np.ndarray) -> bool:
    return bool(np.allclose(np.abs(rotation), np.round(np.abs(rotation)), atol=1e-9))


@lru_cache(maxsize=32)
def _parsed(path: Path, mtime: float):
    root = ElementTree.parse(path).getroot()
    links = {link.get("name"): link for link in root.findall("link")}
    joints = [
        (j.get("name"), j.get("type"), j.find("parent").get("link"), j.find("child").get("link"), j)
        for j in root.findall("joint")
    ]
    return links, joints


def read_fixture(name: str, urdf: Path, spec, frame: TaskFrame) -> FixtureModel:
    """The fixture `spec` (a FixtureSpec) named `name`, from `urdf`, stood in the world by `frame`."""
    links, joints = _parsed(urdf, urdf.stat().st_mtime)
    children = {child for _, _, _, child, _ in joints}
    roots = [link for link in links if link not in children]
    if len(roots) != 1:
        raise FixtureError(f"{urdf.name}: a fixture is one tree of links with one root; roots: {roots}")
    moving = [(jname, kind) for jname, kind, *_ in joints if kind != "fixed"]
    names = [jname for jname, _ in moving]
    if names != [spec.joint]:
        known = ", ".join(f"{jname} ({kind})" for jname, kind in moving) or "none"
        where = (
            f"no moving joint {spec.joint!r} in {urdf.name}{suggest(spec.joint, names)}"
            if spec.joint not in names
            else ""
        )
        raise FixtureError(f"{where or urdf.name}: a fixture moves on one joint (its moving joints: {known})", "joint")
    if moving[0][1] != "prismatic":
        raise FixtureError(
            f"joint {spec.joint!r} is {moving[0][1]}: a fixture's joint is prismatic (a drawer)", "joint"
        )
    unknown = sorted(set(spec.touchable) - set(links))
    if unknown:
        raise FixtureError(f"no link {unknown[0]!r} in {urdf.name}{suggest(unknown[0], list(links))}", "touchable")

    turn = pin.rpy.rpyToMatrix(0.0, 0.0, np.radians(spec.yaw))
    rotation = frame.rotation @ turn
    base = frame.to_world(spec.position)
    world_of = {roots[0]: (pin.SE3(rotation, base), False)}
    lower = upper = 0.0
    travel = point = None
    pending = list(joints)
    while pending:  # parents before children, whatever order the file lists them in
        placed = [j for j in pending if j[2] in world_of]
        if not placed:
            raise FixtureError(f"{urdf.name}: joints {[j[0] for j in pending]} hang from no placed link")
        for joint in placed:
            pending.remove(joint)
            jname, kind, parent, child, element = joint
            parent_pose, parent_moves = world_of[parent]
            pose = parent_pose * _origin(element)
            moves = parent_moves
            if kind == "prismatic":
                limit = element.find("limit")
                if limit is None or limit.get("lower") is None or limit.get("upper") is None:
                    raise FixtureError(f"joint {jname!r} has no <limit lower upper>: the checks need its travel")
                lower, upper = float(limit.get("lower")), float(limit.get("upper"))
                axis = _vector(element.find("axis").get("xyz") if element.find("axis") is not None else "1 0 0")
                travel = pose.rotation @ (axis / np.linalg.norm(axis))
                pose = pin.SE3(pose.rotation, pose.translation + travel * lower)
                point, moves = pose.translation.copy(), True
            world_of[child] = (pose, moves)
    boxes = []
    for link, (pose, moves) in world_of.items():
        for index, collision in enumerate(links[link].findall("collision")):
            label = collision.get("name") or f"#{index}"
            box = collision.find("geometry/box")
            if box is None:
                shape = next(iter(collision.find("geometry")), None)
                raise FixtureError(
                    f"{urdf.name}: link {link!r} collision {label!r} is a {getattr(shape, 'tag', 'missing shape')}: "
                    "a fixture's collision shapes are boxes (the safety check's obstacles are boxes)"
                )
            placed = pose * _origin(collision)
            if not _axis_aligned(placed.rotation):
                raise FixtureError(
                    f"{urdf.name}: link {link!r} collision {label!r} is not axis-aligned in the world (yaw "
                    f"{spec.yaw}°): the safety check's obstacles are axis-aligned boxes",
                    "yaw",
                )
            half = np.abs(placed.rotation) @ (_vector(box.get("size")) / 2)
            depth = float(spec.touch_depth) if link in spec.touchable else 0.0
            boxes.append(FixtureBox(link, label, placed.translation.copy(), half, moves, depth))
    return FixtureModel(
        name,
        urdf,
        spec.joint,
        lower,
        upper,
        travel,
        point,
        rotation,
        base,
        tuple(boxes),
        float(spec.friction),
        float(spec.damping),
    )


def fixture_models(spec, folders: dict[str, Path] | None = None) -> dict[str, FixtureModel]:
    """Every fixture of a composed spec, by name; `folders`: the folder each fixture's URDF path is relative to."""
    frame = TaskFrame.of(spec.robot)
    folders = folders or {}
    return {
        name: read_fixture(name, fixture_urdf(fixture.urdf, folders.get(name)), fixture, frame)
        for name, fixture in spec.task.fixtures.items()
    }
