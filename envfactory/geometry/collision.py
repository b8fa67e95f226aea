"""The robot's collision geometry against the scene and against itself.

Every link's collision shapes come from the URDF through Pinocchio's
GeometryModel (meshes as their convex hulls) and coal measures exact
distances. Each shape is also wrapped in a capsule fitted around it: capsules
give lower bounds on every distance for the price of one compiled pass
(capsule_kernel), and coal runs only for the pairs those bounds leave
undecided.

Distances here are clearances: the exact gap minus the links' padding, in
metres, negative when shapes overlap. They are in the robot base frame.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from functools import cached_property

import coal
import numpy as np
import pinocchio as pin

from envfactory.geometry import capsule_kernel
from envfactory.geometry.gripper_sweep import GripperSweep
from envfactory.geometry.kinematics import Kinematics
from envfactory.geometry.obstacles import Obstacle


class PairRules(dict):
    """What a generated pair list says of the self pairs: shape-name pairs -> why they are skipped (the
    mapping itself), and in `margins` shape-name pairs -> the smaller margin (m) each keeps instead of the
    surface margin: pairs the robot's design holds inside the surface margin, measured against a margin of
    their own rather than skipped."""

    def __init__(self, skipped=(), margins=None):
        super().__init__(skipped)
        self.margins: dict[frozenset, float] = dict(margins or {})


@dataclass(frozen=True)
class Shape:
    """One collision shape of the robot, with the capsule and the box that enclose it (parent joint frame)."""

    name: str
    link: str
    joint: int  # Pinocchio joint the shape rides on; 0 for the fixed base
    capsule_start: np.ndarray
    capsule_end: np.ndarray
    radius: float  # capsule radius, padding included
    padding: float
    box: tuple[np.ndarray, np.ndarray, np.ndarray]  # around the shape: flat links (fingers, pads) fit a box far better

    @cached_property  # read per gripper sample when the finger table is built
    def corners(self) -> np.ndarray:
        """The box's 8 corners (box_corners' order), each pushed out by BOX_ROUNDING."""
        corners = box_corners(*self.box)
        return corners + np.sign(corners - self.box[0]) * BOX_ROUNDING


_AXES = {"X": np.array([1.0, 0.0, 0.0]), "Y": np.array([0.0, 1.0, 0.0]), "Z": np.array([0.0, 0.0, 1.0])}


def _revolute_axis(joint_model) -> np.ndarray | None:
    """The unit axis of a revolute joint in its own frame, or None if it is not one we can read."""
    kind = joint_model.shortname()
    for prefix in ("JointModelRUB", "JointModelR"):
        if kind.startswith(prefix) and kind[len(prefix):] in _AXES:
            return _AXES[kind[len(prefix):]]
    if kind in ("JointModelRevoluteUnaligned", "JointModelRevoluteUnboundedUnaligned"):
        axis = np.asarray(joint_model.extract().axis, float)
        return axis / np.linalg.norm(axis)
    return None


def shape_points(geometry) -> np.ndarray:
    """Points whose convex hull is the shape (cylinders and spheres: their capsule's axis)."""
    if isinstance(geometry, coal.Box):
        half = np.asarray(geometry.halfSide)
        return np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
    if isinstance(geometry, coal.ConvexBase):
        return np.asarray(geometry.points())
    if isinstance(geometry, coal.BVHModelBase):
        return np.asarray(geometry.vertices())
    raise TypeError(type(geometry).__name__)


def fit_capsule(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """A capsule containing every point, and so their convex hull: axis along the
    principal direction, radius the largest distance from it."""
    center = points.mean(axis=0)
    offsets = points - center
    axis = np.linalg.svd(offsets, full_matrices=False)[2][0]
    along = offsets @ axis
    across = np.linalg.norm(offsets - np.outer(along, axis), axis=1)
    radius = float(across.max())
    # a point at distance `across` from the axis sits inside the end cap while its
    # projection is within sqrt(r² - across²) of the segment end
    room = np.sqrt(np.maximum(radius**2 - across**2, 0.0))
    low, high = float(np.min(along + room)), float(np.max(along - room))
    if low > high:  # short and round: a sphere does
        middle = center + axis * (low + high) / 2
        radius = float(np.max(np.linalg.norm(points - middle, axis=1)))
        return middle, middle.copy(), radius
    return center + axis * low, center + axis * high, radius


def fit_box_frame(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A box containing every point, aligned with their principal directions: its centre, its axes (rows,
    orthonormal) and its half extents along them."""
    center = points.mean(axis=0)
    axes = np.linalg.svd(points - center, full_matrices=False)[2]
    along = (points - center) @ axes.T
    low, high = along.min(axis=0), along.max(axis=0)
    return center + ((low + high) / 2) @ axes, axes, (high - low) / 2


# a nanometre out from the centre along each coordinate: rounding must not shrink a box
BOX_ROUNDING = 1e-9


def box_corners(center: np.ndarray, axes: np.ndarray, half: np.ndarray) -> np.ndarray:
    """The 8 corners of a box, x-, y- and z-steps 4, 2 and 1 apart in the list."""
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    return center + (signs * half) @ axes


def _box_of(geometry_object) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The box around a shape (parent joint frame): centre, axes (rows), half extents."""
    geometry, placement = geometry_object.geometry, geometry_object.placement
    if isinstance(geometry, (coal.Cylinder, coal.Capsule, coal.Sphere)):
        radius = float(geometry.radius)
        # half height along the shape's z: a cylinder's half length, a capsule's plus its cap, a sphere's radius
        if isinstance(geometry, coal.Sphere):
            half = radius
        else:
            half = float(geometry.halfLength) + (radius if isinstance(geometry, coal.Capsule) else 0.0)
        local = np.array([[sx * radius, sy * radius, sz * half] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    else:
        local = shape_points(geometry)
    return fit_box_frame(local @ placement.rotation.T + placement.translation)


def _capsule_of(geometry_object) -> tuple[np.ndarray, np.ndarray, float]:
    geometry, placement = geometry_object.geometry, geometry_object.placement
    if isinstance(geometry, (coal.Cylinder, coal.Capsule)):
        half = float(geometry.halfLength)
        start, end = placement.act(np.array([0.0, 0.0, -half])), placement.act(np.array([0.0, 0.0, half]))
        return start, end, float(geometry.radius)
    if isinstance(geometry, coal.Sphere):
        center = placement.translation.copy()
        return center, center.copy(), float(geometry.radius)
    local = shape_points(geometry)
    start, end, radius = fit_capsule(local @ placement.rotation.T + placement.translation)
    return start, end, radius * (1 + 1e-9) + 1e-9


@dataclass
class MotionProof:
    """What the compiled proof of a motion found (capsule_kernel.motion_proof): its outcome, whether the gripper's
    motion closes any pair, and per pair the travel, reserve and bounds at the start and end it measured, and the
    pairs it left unproven between the ends."""

    outcome: int
    gripper_moves: bool
    travel: np.ndarray
    reserve: np.ndarray
    start_bound: np.ndarray
    end_bound: np.ndarray
    unproven: np.ndarray


class CollisionModel:
    """The robot's shapes, the scene's obstacles, and the pairs between them that are measured."""

    def __init__(self, kinematics: Kinematics, obstacles: list[Obstacle], padding: dict[str, float] | None = None):
        self.kinematics = kinematics
        model = kinematics.model
        self.geometry = pin.buildGeomFromUrdf(model, str(kinematics.urdf_path), pin.GeometryType.COLLISION)
        padding = padding or {}
        self.shapes: list[Shape] = []
        for geometry_object in self.geometry.geometryObjects:
            if isinstance(geometry_object.geometry, coal.BVHModelBase):
                # coal measures meshes as the convex hull of their vertices, as PyBullet simulates them
                geometry_object.geometry.buildConvexHull(True, "Qt")
                geometry_object.geometry = geometry_object.geometry.convex
            link = model.frames[geometry_object.parentFrame].name
            start, end, radius = _capsule_of(geometry_object)
            pad = float(padding.get(link, 0.0))
            self.shapes.append(Shape(geometry_object.name, link, int(geometry_object.parentJoint), start, end,
                                     radius + pad, pad, _box_of(geometry_object)))
        self.links = sorted({shape.link for shape in self.shapes})

        # the obstacles, in the robot base frame, join the geometry model on the universe joint
        self.obstacles = obstacles
        base_in_world = np.asarray(kinematics.robot.mount, float)
        self.obstacle_low = np.array([o.low for o in obstacles], float).reshape(-1, 3) - base_in_world
        self.obstacle_high = np.array([o.high for o in obstacles], float).reshape(-1, 3) - base_in_world
        first_obstacle = len(self.shapes)
        for obstacle, low, high in zip(obstacles, self.obstacle_low, self.obstacle_high):
            box = coal.Box(*(high - low))
            self.geometry.addGeometryObject(pin.GeometryObject(f"obstacle:{obstacle.name}", 0, 0,
                                                               pin.SE3(np.eye(3), (low + high) / 2), box))

        drivers = kinematics.coordinate_drivers()
        self.coordinates = len(kinematics.robot.arm_joints) + (kinematics.robot.gripper is not None)
        moved = [self._is_moved(shape.joint, drivers) for shape in self.shapes]
        # the fingers: shapes the gripper moves (the rest of the arm holds still when only the gripper moves)
        gripper = self.coordinates - 1 if kinematics.robot.gripper is not None else None
        self.moved_by_gripper = np.array([gripper is not None and self._is_moved(shape.joint, drivers, gripper)
                                          for shape in self.shapes], dtype=bool)
        self.lever = np.array([self._lever(shape, drivers) for shape in self.shapes])  # (shapes, coordinates)
        # per shape, the nearest joint at or above it that the gripper does not move
        self.gripper_mount = np.array([self._gripper_mount(shape.joint, drivers) for shape in self.shapes],
                                      dtype=np.int64)
        if kinematics.robot.gripper is not None:
            # a shape the gripper does not move has no gripper lever (the measured sweep leaves rounding noise)
            self.lever[:, -1] = np.where(self.moved_by_gripper, self._gripper_levers(drivers), 0.0)

        moving = np.flatnonzero(moved)
        self.scene_shape = np.repeat(moving, len(obstacles))
        self.scene_obstacle = np.tile(np.arange(len(obstacles)), len(moving))
        self.self_pairs: list[tuple[int, int, str]] = []  # (shape, shape, why a pair is skipped or "")
        for a in range(len(self.shapes)):
            for b in range(a + 1, len(self.shapes)):
                self.self_pairs.append((a, b, self._structural_exemption(a, b, drivers)))
        self._pin_pairs_scene = np.array([self._add_pair(s, first_obstacle + o)
                                          for s, o in zip(self.scene_shape, self.scene_obstacle)], dtype=int)
        self.radius = np.array([shape.radius for shape in self.shapes])
        self.padding = np.array([shape.padding for shape in self.shapes])
        self.moving_shapes = moving
        # what the compiled bounds need, as flat arrays
        self._joints = capsule_kernel.JointTable(model, drivers)
        self._frames = np.zeros((model.njoints, 3, 4))
        self._shape_joint = np.array([shape.joint for shape in self.shapes], dtype=np.int64)
        self._local_ends = np.array([[shape.capsule_start, shape.capsule_end] for shape in self.shapes])
        self._local_corners = np.array([shape.corners for shape in self.shapes])
        # the same boxes as centre, axes and half extents (grown to hold the corners' push) for separating them
        self._local_boxes = np.array([[shape.box[0], *shape.box[1]] for shape in self.shapes])  # (shapes, 4, 3)
        self._box_half = np.array([shape.box[2] + 2 * BOX_ROUNDING for shape in self.shapes])
        self._coordinates = np.zeros(self.coordinates)
        self._frames_current = self._pinocchio_current = False
        self.gripper_sweep = GripperSweep(self)
        self.set_ignored_pairs({})
        self.data = model.createData()
        self._distance_request = coal.DistanceRequest()

    def measuring_copy(self) -> "CollisionModel":
        """A copy that shares the structure (shapes, pairs, levers, compiled tables, the gripper sweep's
        table) and owns the measuring state: the pose, the placed frames, Pinocchio's and coal's data.
        Envs of one robot share the structure, built once per process, each measuring with its own copy."""
        twin = copy.copy(self)
        twin.kinematics = self.kinematics.measuring_copy()
        twin._frames = np.zeros_like(self._frames)
        twin._coordinates = np.zeros_like(self._coordinates)
        twin._frames_current = twin._pinocchio_current = False
        twin.geometry_data = self.geometry.createData()
        twin.data = self.kinematics.model.createData()
        twin.gripper_sweep = copy.copy(self.gripper_sweep)
        twin.gripper_sweep.collision = twin
        return twin


    # ----------------------------------------------------------- structure

    def _is_moved(self, joint: int, drivers, coordinate: int | None = None) -> bool:
        """Whether the joint or one above it is driven (by `coordinate`, if given)."""
        while joint > 0:
            if joint in drivers and (coordinate is None or drivers[joint][0] == coordinate):
                return True
            joint = self.kinematics.model.parents[joint]
        return False

    def _path(self, joint_a: int, joint_b: int) -> tuple[list[int], int]:
        """The joints between two bodies (those on either branch below their common ancestor),
        and that common ancestor."""
        parents = self.kinematics.model.parents
        ancestors_a, joint = [], joint_a
        while True:
            ancestors_a.append(joint)
            if joint == 0:
                break
            joint = parents[joint]
        path_b, joint = [], joint_b
        while joint not in ancestors_a:
            path_b.append(joint)
            joint = parents[joint]
        return ancestors_a[: ancestors_a.index(joint)] + path_b, joint

    def _structural_exemption(self, a: int, b: int, drivers) -> str:
        shape_a, shape_b = self.shapes[a], self.shapes[b]
        path, _ = self._path(shape_a.joint, shape_b.joint)
        driven = [j for j in path if j in drivers]
        if not driven:
            return "rigidly joined"
        gripper = self.coordinates - 1 if self.kinematics.robot.gripper is not None else None
        if all(drivers[j][0] == gripper for j in driven):
            return "gripper mechanism"  # only the gripper moves them against each other: its own design
        if len(path) == 1:
            return "adjacent"
        return ""

    def _lever(self, shape: Shape, drivers, above: int = 0) -> np.ndarray:
        """How far any point of the shape can move per unit change of each coordinate, relative to
        joint `above` (the base by default). A revolute joint moves a point by its distance from the
        joint's axis, bounded by the offset of the next joint down the chain from that axis plus the
        summed link lengths from there to the farthest point of the capsule. The gripper column is
        replaced by a measured sweep."""
        model = self.kinematics.model
        lever = np.zeros(self.coordinates)
        ends = (shape.capsule_start, shape.capsule_end)
        reach = max(np.linalg.norm(end) for end in ends) + shape.radius  # from the current joint's origin
        child_offset, child_reach = None, 0.0  # the joint below, seen from the current one
        joint = shape.joint
        while joint > above:
            kind = model.joints[joint].shortname()
            prismatic = "Prismatic" in kind or kind.startswith("JointModelP")
            if joint in drivers:
                coordinate, gain = drivers[joint]
                axis = _revolute_axis(model.joints[joint])
                if prismatic:
                    arm = 1.0
                elif axis is None:
                    arm = reach
                elif child_offset is None:  # the shape's own joint: its points are fixed in this frame
                    arm = max(np.linalg.norm(np.cross(end, axis)) for end in ends) + shape.radius
                else:
                    arm = min(reach, float(np.linalg.norm(np.cross(child_offset, axis))) + child_reach)
                lever[coordinate] += abs(gain) * arm
            child_offset, child_reach = model.jointPlacements[joint].translation, reach
            if prismatic:  # the slide lengthens every lever above it by its travel
                travel = max(abs(model.lowerPositionLimit[model.idx_qs[joint]]),
                             abs(model.upperPositionLimit[model.idx_qs[joint]]))
                reach += travel
                child_reach += travel
            reach += float(np.linalg.norm(child_offset))
            joint = model.parents[joint]
        return lever

    def _relative_lever(self, a: int, b: int, drivers) -> np.ndarray:
        """Levers of two shapes against each other: joints above both move them as one body."""
        shape_a, shape_b = self.shapes[a], self.shapes[b]
        _, common = self._path(shape_a.joint, shape_b.joint)
        levers = []
        for this, other in ((a, b), (b, a)):
            # turning a joint about an axis that `this` is round about cannot change the pair's distance
            below = self._round_about(this, other, common, drivers)
            levers.append(self._lever(self.shapes[other], drivers, below if below is not None else common))
        lever = levers[0] + levers[1]
        if self.kinematics.robot.gripper is not None:
            lever[-1] = self.lever[a, -1] + self.lever[b, -1]
        return lever

    def _round_about(self, this: int, other: int, common: int, drivers) -> int | None:
        """The driven revolute joint right below `common` on the way to shape `other`, if shape `this`
        is fixed to `common` and round about that joint's axis (a sphere centred on it, a cylinder or
        capsule along it); else None."""
        model = self.kinematics.model
        if self.shapes[this].joint != common or self.shapes[other].joint == common:
            return None
        joint = self.shapes[other].joint
        while model.parents[joint] != common:
            joint = model.parents[joint]
        axis = _revolute_axis(model.joints[joint])
        if joint not in drivers or axis is None:
            return None
        placement = model.jointPlacements[joint]
        origin, direction = placement.translation, placement.rotation @ axis
        geometry_object = self.geometry.geometryObjects[this]
        centre = geometry_object.placement.translation
        on_axis = float(np.linalg.norm(np.cross(centre - origin, direction))) < 1e-9
        if isinstance(geometry_object.geometry, coal.Sphere):
            return joint if on_axis else None
        if isinstance(geometry_object.geometry, (coal.Cylinder, coal.Capsule)):
            along = float(np.linalg.norm(np.cross(geometry_object.placement.rotation[:, 2], direction))) < 1e-9
            return joint if on_axis and along else None
        return None

    GRIPPER_SAMPLES = 400
    GRIPPER_SAFETY_FACTOR = 1.25

    def _gripper_levers(self, drivers) -> np.ndarray:
        """How far any point of each shape moves per unit of gripper travel, measured along the gripper's
        one-dimensional range. A linkage's joints turn against each other (a parallel gripper keeps its
        pads upright), so the summed joint levers would overstate the motion several times; a dense
        sweep with a safety factor bounds it instead."""
        gripper = self.kinematics.robot.gripper
        values = np.linspace(gripper.low, gripper.high, self.GRIPPER_SAMPLES)
        frames = self.mounted_placements(range(len(self.shapes)), values)
        levers = np.zeros(len(self.shapes))
        step = values[1] - values[0]
        for index, shape in enumerate(self.shapes):
            rate = 0.0
            for before, after in zip(frames[:-1], frames[1:]):
                a, b = before[index], after[index]
                moved = max(np.linalg.norm(b.act(shape.capsule_start) - a.act(shape.capsule_start)),
                            np.linalg.norm(b.act(shape.capsule_end) - a.act(shape.capsule_end)))
                turned = np.linalg.norm(pin.log3(b.rotation @ a.rotation.T))
                rate = max(rate, (moved + shape.radius * turned) / step)
            levers[index] = self.GRIPPER_SAFETY_FACTOR * rate
        return levers

    def mounted_placements(self, shapes, values) -> list[list[pin.SE3]]:
        """Per gripper value, each of these shapes' joint frame in the frame of its gripper mount: where
        the gripper alone puts it (the arm's pose moves shape and mount together)."""
        kin, model = self.kinematics, self.kinematics.model
        data = model.createData()
        q_arm = np.zeros(len(kin.robot.arm_joints))
        out = []
        for value in values:
            pin.forwardKinematics(model, data, kin.full_q(q_arm, value))
            out.append([data.oMi[int(self.gripper_mount[s])].actInv(data.oMi[self.shapes[s].joint]) for s in shapes])
        return out

    def _gripper_mount(self, joint: int, drivers) -> int:
        """The nearest joint at or above this one that the gripper does not move."""
        gripper = self.coordinates - 1
        while joint > 0 and joint in drivers and drivers[joint][0] == gripper:
            joint = self.kinematics.model.parents[joint]
        return joint

    def _add_pair(self, first: int, second: int) -> int:
        self.geometry.addCollisionPair(pin.CollisionPair(int(first), int(second)))
        return len(self.geometry.collisionPairs) - 1

    def set_ignored_pairs(self, ignored: dict[frozenset, str]) -> None:
        """Skip the self pairs a sampled allowed-collision list names (shape-name pairs -> reason); a
        PairRules also gives measured pairs their own margins (`pair_margin`)."""
        margins = getattr(ignored, "margins", {})
        self.ignored = {}
        checked, own = [], []
        for a, b, why in self.self_pairs:
            key = frozenset((self.shapes[a].name, self.shapes[b].name))
            why = why or ignored.get(key, "")
            if why:
                self.ignored[key] = why
            else:
                checked.append((a, b))
                own.append(margins.get(key, np.nan))
        self.self_a = np.array([a for a, _ in checked], dtype=int)
        self.self_b = np.array([b for _, b in checked], dtype=int)
        # per measured pair, the margin it keeps instead of the surface margin; NaN: the surface margin
        self.pair_margin = np.concatenate([np.full(len(self.scene_shape), np.nan), np.array(own, float)])
        existing = {(p.first, p.second): k for k, p in enumerate(self.geometry.collisionPairs)}
        self._pin_pairs_self = np.array([existing.get((a, b)) if (a, b) in existing else self._add_pair(a, b)
                                         for a, b in checked], dtype=int)
        self.geometry_data = self.geometry.createData()
        drivers = self.kinematics.coordinate_drivers()
        relative = [self._relative_lever(a, b, drivers) for a, b in checked]
        self.pair_lever = np.vstack([self.lever[self.scene_shape], *relative]) if relative \
            else self.lever[self.scene_shape]
        self.pair_padding = np.concatenate([self.padding[self.scene_shape],
                                            self.padding[self.self_a] + self.padding[self.self_b]])
        self._pin_pairs = np.concatenate([self._pin_pairs_scene, self._pin_pairs_self]).astype(int)
        # the same as plain Python numbers: a query's own cost is a microsecond or two, numpy's scalar
        # indexing around it would cost more
        self._pin_pair_of = self._pin_pairs.tolist()
        self._padding_of = self.pair_padding.tolist()
        self.gripper_sweep.index_pairs()

    @property
    def pair_count(self) -> int:
        return len(self._pin_pairs)

    def pair_names(self, pair: int) -> tuple[str, str]:
        """The link and the obstacle or link a measured pair names."""
        scene = len(self.scene_shape)
        if pair < scene:
            return self.shapes[self.scene_shape[pair]].link, self.obstacles[self.scene_obstacle[pair]].name
        pair -= scene
        return self.shapes[self.self_a[pair]].link, self.shapes[self.self_b[pair]].link

    # ----------------------------------------------------------- measuring

    def pose(self, q_arm: np.ndarray, gripper: float) -> None:
        """Place every shape at this configuration (each measure computes the frames it needs once)."""
        arm = len(q_arm)
        self._coordinates[:arm] = q_arm
        if self.coordinates > arm:
            self._coordinates[arm] = gripper
        self._frames_current = self._pinocchio_current = False

    def _place_frames(self) -> None:
        if not self._frames_current:
            joints = self._joints
            capsule_kernel.joint_frames(self._coordinates, joints.parent, joints.placement, joints.kind, joints.axis,
                                        joints.coordinate, joints.gain, self._frames)
            self._frames_current = True

    def sphere_gaps(self, shapes: np.ndarray, center: np.ndarray, radius: float) -> np.ndarray:
        """Gaps between these shapes' capsules at the current pose and a sphere (base frame), negative where
        they overlap: a lower bound on the gap between anything inside them."""
        self._place_frames()
        out = np.empty(len(shapes))
        capsule_kernel.shape_sphere_gaps(self._frames, self._shape_joint, self._local_ends, self.radius, shapes,
                                         np.ascontiguousarray(center, float), float(radius), out)
        return out

    def bounds(self) -> np.ndarray:
        """A lower bound on the clearance of every measured pair at the current pose."""
        self._place_frames()
        out = np.empty(self.pair_count)
        capsule_kernel.capsule_bounds(self._frames, self._shape_joint, self._local_ends, self.radius,
                                      self._local_boxes, self._box_half, self.padding, self.moving_shapes,
                                      self.obstacle_low, self.obstacle_high, self.self_a, self.self_b, out)
        return out

    def unproven_by_capsules(self, q_from: np.ndarray, way: np.ndarray, gripper: float, pairs: np.ndarray,
                             start_bound: np.ndarray, end_bound: np.ndarray, travel: np.ndarray,
                             reserve: np.ndarray, threshold: np.ndarray, levels: int, deeper: int = 0) -> np.ndarray:
        """Of these pairs, those the capsule bounds cannot prove clear along the straight arm motion q_from +
        f way (gripper fixed at `gripper`, less each pair's reserve), halving every piece up to `levels` times,
        then a pair's unproven pieces `deeper` times more (capsule_kernel.capsule_motion_unproven). Leaves the
        model posed nowhere in particular."""
        coordinates = self._coordinates
        if self.coordinates > len(q_from):
            coordinates[len(q_from)] = gripper
        unproven = np.empty(len(pairs), dtype=np.bool_)
        joints = self._joints
        capsule_kernel.capsule_motion_unproven(coordinates, q_from, way, pairs, start_bound, end_bound, travel, reserve,
                                               threshold, levels, deeper, joints.parent, joints.placement, joints.kind,
                                               joints.axis, joints.coordinate, joints.gain, self._shape_joint,
                                               self._local_ends, self._local_boxes, self._box_half, self.radius,
                                               self.padding, self.moving_shapes, self.obstacle_low, self.obstacle_high,
                                               self.self_a, self.self_b, unproven)
        self.forget_pose()
        return pairs[unproven]

    def motion_proof(self, q_from: np.ndarray, way: np.ndarray, gripper_from: float, gripper_to: float,
                     margin: np.ndarray, last: tuple[np.ndarray, np.ndarray, float] | None, reuse_within: float,
                     levels: int, deeper: int) -> MotionProof:
        """The capsule bounds' proof that the straight arm motion q_from + f way keeps every pair its margin, with the
        gripper anywhere between its two values, in one compiled call (capsule_kernel.motion_proof). `last`: the
        arm pose, bounds and gripper widening (how far this motion's gripper range reaches beyond theirs) of the
        last proven end, which stand in for the start's bounds if the arm is within `reuse_within` of it."""
        count = self.pair_count
        travel, reserve, start, end = np.empty(count), np.empty(count), np.empty(count), np.empty(count)
        unproven = np.empty(count, dtype=np.bool_)
        last_q, last_bound, beyond = last if last is not None else (q_from, start, 0.0)
        joints = self._joints
        outcome, moves = capsule_kernel.motion_proof(
            self._coordinates, q_from, way, (gripper_from + gripper_to) / 2, abs(gripper_to - gripper_from),
            self.pair_lever, margin, last is not None, last_q, last_bound, beyond, reuse_within, levels, deeper,
            joints.parent, joints.placement, joints.kind, joints.axis, joints.coordinate, joints.gain,
            self._shape_joint, self._local_ends, self._local_boxes, self._box_half, self.radius, self.padding,
            self.moving_shapes, self.obstacle_low, self.obstacle_high, self.self_a, self.self_b, travel, reserve, start,
            end, unproven)
        self.forget_pose()
        return MotionProof(int(outcome), bool(moves), travel, reserve, start, end, unproven.nonzero()[0])

    def forget_pose(self) -> None:
        """A compiled pass posed the coordinates along a motion: the frames and placements no longer match any
        pose() call, and pose() must come before the next measure."""
        self._frames_current = self._pinocchio_current = False

    def _place_geometry(self) -> None:
        if not self._pinocchio_current:
            arm = len(self.kinematics.robot.arm_joints)
            q = self.kinematics.full_q(self._coordinates[:arm], self._coordinates[arm] if self.coordinates > arm else 0.0)
            pin.forwardKinematics(self.kinematics.model, self.data, q)
            pin.updateGeometryPlacements(self.kinematics.model, self.data, self.geometry, self.geometry_data)
            self._pinocchio_current = True

    def exact(self, pairs: np.ndarray) -> np.ndarray:
        """coal's clearance of the given measured pairs at the current pose."""
        return np.array([self.exact_one(pair) for pair in np.asarray(pairs).tolist()], dtype=float)

    def exact_one(self, pair: int) -> float:
        """coal's clearance of one measured pair at the current pose."""
        self._place_geometry()
        result = pin.computeDistance(self.geometry, self.geometry_data, self._pin_pair_of[pair])
        return result.min_distance - self._padding_of[pair]

    def all_exact(self) -> np.ndarray:
        return self.exact(np.arange(self.pair_count))

    def box_clearances(self, shapes: np.ndarray, box: coal.Box, center: np.ndarray, rotation: np.ndarray) -> np.ndarray:
        """coal's clearance of the given shapes from a box outside the scene (an object; base frame)
        at the current pose."""
        self._place_geometry()
        placement = coal.Transform3s(rotation, center)
        out = np.empty(len(shapes))
        for row, shape in enumerate(shapes):
            pose = self.geometry_data.oMg[int(shape)]
            out[row] = coal.distance(self.geometry.geometryObjects[int(shape)].geometry,
                                     coal.Transform3s(pose.rotation, pose.translation), box, placement,
                                     self._distance_request, coal.DistanceResult()) - self.padding[shape]
        return out
