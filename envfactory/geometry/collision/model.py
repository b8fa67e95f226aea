"""The robot's collision geometry against the scene and against itself.

Every link's collision shapes come from the URDF through Pinocchio's GeometryModel (meshes as their convex
hulls) and coal measures exact distances. Each shape is also wrapped in a capsule fitted around it
(shapes.py): capsules give lower bounds on every distance for the price of one compiled pass
(geometry/kernels/), and coal runs only for the pairs those bounds leave undecided. What the shapes are to
each other (their levers, the fingers' mounts, the exempt pairs) is structure.py's.

Distances here are clearances: the exact gap minus the links' padding, in metres, negative when shapes
overlap. They are in the robot base frame.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import coal
import numpy as np
import pinocchio as pin

from envfactory.geometry.collision.hull_store import mesh_hull
from envfactory.geometry.collision.meshes import with_meshes_stood_in
from envfactory.geometry.collision.shapes import BOX_ROUNDING, Shape, box_of, capsule_of
from envfactory.geometry.collision.structure import Structure
from envfactory.geometry.gripper_sweep import GripperSweep
from envfactory.geometry.kernels.serving import kernels
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


@dataclass
class MotionProof:
    """What the compiled proof of a motion found (motion_proof): its outcome, whether the gripper's
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
        urdf, stood_in = with_meshes_stood_in(kinematics.urdf_path)
        self.geometry = pin.buildGeomFromUrdf(model, str(urdf), pin.GeometryType.COLLISION)
        padding = padding or {}
        self.shapes: list[Shape] = []
        hulls = {}  # a gripper's mirrored fingers name the same mesh twice: one hull serves both (coal only reads it)
        for geometry_object in self.geometry.geometryObjects:
            if geometry_object.name in stood_in:
                mesh_file, scale = stood_in.pop(geometry_object.name)
                key = (mesh_file, scale.tobytes())
                if key not in hulls:
                    hulls[key] = mesh_hull(mesh_file, scale)
                geometry_object.geometry = hulls[key]
            elif isinstance(geometry_object.geometry, coal.BVHModelBase):
                # coal measures meshes as the convex hull of their vertices, as PyBullet simulates them
                geometry_object.geometry.buildConvexHull(True, "Qt")
                geometry_object.geometry = geometry_object.geometry.convex
            link = model.frames[geometry_object.parentFrame].name
            start, end, radius = capsule_of(geometry_object)
            pad = float(padding.get(link, 0.0))
            self.shapes.append(
                Shape(
                    geometry_object.name,
                    link,
                    int(geometry_object.parentJoint),
                    start,
                    end,
                    radius + pad,
                    pad,
                    box_of(geometry_object),
                )
            )
        if stood_in:  # Pinocchio named a shape otherwise than <link>_<index>: its stand-in sphere would be measured
            raise RuntimeError(f"{kinematics.urdf_path}: no shape named {sorted(stood_in)} to take its collision mesh")
        self.links = sorted({shape.link for shape in self.shapes})

        # the obstacles, in the robot base frame, join the geometry model on the universe joint
        self.obstacles = obstacles
        base_in_world = np.asarray(kinematics.robot.mount, float)
        self.obstacle_low = np.array([o.low for o in obstacles], float).reshape(-1, 3) - base_in_world
        self.obstacle_high = np.array([o.high for o in obstacles], float).reshape(-1, 3) - base_in_world
        first_obstacle = len(self.shapes)
        for obstacle, low, high in zip(obstacles, self.obstacle_low, self.obstacle_high):
            box = coal.Box(*(high - low))
            self.geometry.addGeometryObject(
                pin.GeometryObject(f"obstacle:{obstacle.name}", 0, 0, pin.SE3(np.eye(3), (low + high) / 2), box)
            )

        self.structure = structure = Structure(kinematics, self.geometry, self.shapes)
        self.coordinates, moved = structure.coordinates, structure.moved
        self.moved_by_gripper, self.lever, self.gripper_mount = (
            structure.moved_by_gripper,
            structure.lever,
            structure.gripper_mount,
        )

        moving = np.flatnonzero(moved)
        # every moving shape against every obstacle, in the order the compiled kernels number them
        self.scene_shape = np.repeat(moving, len(obstacles))
        self.scene_obstacle = np.tile(np.arange(len(obstacles)), len(moving))
        # a touchable part (a drawer's handle) is for the fingers: their pairs with it keep a negative margin, the
        # depth a closing grip may command them into it
        depth = np.array([o.touch_depth for o in obstacles], dtype=float)
        self._scene_margin = np.where(
            (depth[self.scene_obstacle] > 0) & self.moved_by_gripper[self.scene_shape],
            -depth[self.scene_obstacle],
            np.nan,
        )
        # obstacles riding on a fixture's joint: their rows at the joint's lower limit, and their travel per unit
        self._fixture_rows = {}
        for row, obstacle in enumerate(obstacles):
            if obstacle.moves:
                self._fixture_rows.setdefault(obstacle.fixture, []).append(row)
        # the measured pairs of a gripper shape with a touchable part, per fixture (fixture_hold.py)
        touch = np.flatnonzero(np.isfinite(self._scene_margin))
        self.touch_pairs = {
            name: touch[[obstacles[self.scene_obstacle[pair]].fixture == name for pair in touch]]
            for name in {obstacles[self.scene_obstacle[pair]].fixture for pair in touch}
        }
        self._closed_low, self._closed_high = self.obstacle_low.copy(), self.obstacle_high.copy()
        self._travel = np.array([o.travel for o in obstacles], float).reshape(-1, 3)
        self._first_obstacle = first_obstacle
        self._fixture_values: dict[str, float] = {}
        self.self_pairs: list[tuple[int, int, str]] = []  # (shape, shape, why a pair is skipped or "")
        for a in range(len(self.shapes)):
            for b in range(a + 1, len(self.shapes)):
                self.self_pairs.append((a, b, structure.exemption(a, b)))
        self._pin_pairs_scene = np.array(
            [self._add_pair(s, first_obstacle + o) for s, o in zip(self.scene_shape, self.scene_obstacle)], dtype=int
        )
        self.radius = np.array([shape.radius for shape in self.shapes])
        self.padding = np.array([shape.padding for shape in self.shapes])
        self.moving_shapes = moving
        # what the compiled bounds need, as flat arrays
        self._joints = kinematics.joint_table
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
        if self._fixture_rows:  # each copy moves its own fixtures' boxes
            twin.obstacle_low, twin.obstacle_high = self._closed_low.copy(), self._closed_high.copy()
            twin._fixture_values = {}
        return twin

    def move_fixture(self, name: str, value: float) -> bool:
        """Put the boxes riding on fixture `name`'s joint where it holds them `value` past its lower limit; whether
        they moved. The shared structure keeps them at the lower limit: only a measuring copy moves its own."""
        rows = self._fixture_rows.get(name)
        if rows is None or self._fixture_values.get(name) == value:
            return False
        shift = self._travel[rows] * value
        self.obstacle_low[rows] = self._closed_low[rows] + shift
        self.obstacle_high[rows] = self._closed_high[rows] + shift
        self._fixture_values[name] = value
        self._pinocchio_current = False
        return True

    def mounted_placements(self, shapes, values) -> list[list[pin.SE3]]:
        """Per gripper value, each of these shapes' joint frame in the frame of its gripper mount."""
        return self.structure.mounted_placements(shapes, values)

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
        self.pair_margin = np.concatenate([self._scene_margin, np.array(own, float)])
        existing = {(p.first, p.second): k for k, p in enumerate(self.geometry.collisionPairs)}
        self._pin_pairs_self = np.array(
            [existing.get((a, b)) if (a, b) in existing else self._add_pair(a, b) for a, b in checked], dtype=int
        )
        self.geometry_data = self.geometry.createData()
        relative = [self.structure.relative_lever(a, b) for a, b in checked]
        self.pair_lever = (
            np.vstack([self.lever[self.scene_shape], *relative]) if relative else self.lever[self.scene_shape]
        )
        self.pair_padding = np.concatenate(
            [self.padding[self.scene_shape], self.padding[self.self_a] + self.padding[self.self_b]]
        )
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
            kernels.joint_frames(
                self._coordinates,
                joints.parent,
                joints.placement,
                joints.kind,
                joints.axis,
                joints.coordinate,
                joints.gain,
                self._frames,
            )
            self._frames_current = True

    def sphere_gaps(self, shapes: np.ndarray, center: np.ndarray, radius: float) -> np.ndarray:
        """Gaps between these shapes' capsules at the current pose and a sphere (base frame), negative where
        they overlap: a lower bound on the gap between anything inside them."""
        self._place_frames()
        out = np.empty(len(shapes))
        kernels.shape_sphere_gaps(
            self._frames,
            self._shape_joint,
            self._local_ends,
            self.radius,
            shapes,
            np.ascontiguousarray(center, float),
            float(radius),
            out,
        )
        return out

    def bounds(self) -> np.ndarray:
        """A lower bound on the clearance of every measured pair at the current pose."""
        self._place_frames()
        out = np.empty(self.pair_count)
        kernels.capsule_bounds(
            self._frames,
            self._shape_joint,
            self._local_ends,
            self.radius,
            self._local_boxes,
            self._box_half,
            self.padding,
            self.moving_shapes,
            self.obstacle_low,
            self.obstacle_high,
            self.self_a,
            self.self_b,
            out,
        )
        return out

    def unproven_by_capsules(
        self,
        q_from: np.ndarray,
        way: np.ndarray,
        gripper: float,
        pairs: np.ndarray,
        start_bound: np.ndarray,
        end_bound: np.ndarray,
        travel: np.ndarray,
        reserve: np.ndarray,
        threshold: np.ndarray,
        levels: int,
        deeper: int = 0,
    ) -> np.ndarray:
        """Of these pairs, those the capsule bounds cannot prove clear along the straight arm motion q_from +
        f way (gripper fixed at `gripper`, less each pair's reserve), halving every piece up to `levels` times,
        then a pair's unproven pieces `deeper` times more (capsule_motion_unproven). Leaves the
        model posed nowhere in particular."""
        coordinates = self._coordinates
        if self.coordinates > len(q_from):
            coordinates[len(q_from)] = gripper
        unproven = np.empty(len(pairs), dtype=np.bool_)
        joints = self._joints
        kernels.capsule_motion_unproven(
            coordinates,
            q_from,
            way,
            pairs,
            start_bound,
            end_bound,
            travel,
            reserve,
            threshold,
            levels,
            deeper,
            joints.parent,
            joints.placement,
            joints.kind,
            joints.axis,
            joints.coordinate,
            joints.gain,
            self._shape_joint,
            self._local_ends,
            self._local_boxes,
            self._box_half,
            self.radius,
            self.padding,
            self.moving_shapes,
            self.obstacle_low,
            self.obstacle_high,
            self.self_a,
            self.self_b,
            unproven,
        )
        self.forget_pose()
        return pairs[unproven]

    def motion_proof(
        self,
        q_from: np.ndarray,
        way: np.ndarray,
        gripper_from: float,
        gripper_to: float,
        margin: np.ndarray,
        last: tuple[np.ndarray, np.ndarray, float] | None,
        reuse_within: float,
        levels: int,
        deeper: int,
    ) -> MotionProof:
        """The capsule bounds' proof that the straight arm motion q_from + f way keeps every pair its margin, with the
        gripper anywhere between its two values, in one compiled call (motion_proof). `last`: the
        arm pose, bounds and gripper widening (how far this motion's gripper range reaches beyond theirs) of the
        last proven end, which stand in for the start's bounds if the arm is within `reuse_within` of it."""
        count = self.pair_count
        travel, reserve, start, end = np.empty(count), np.empty(count), np.empty(count), np.empty(count)
        unproven = np.empty(count, dtype=np.bool_)
        last_q, last_bound, beyond = last if last is not None else (q_from, start, 0.0)
        joints = self._joints
        outcome, moves = kernels.motion_proof(
            self._coordinates,
            q_from,
            way,
            (gripper_from + gripper_to) / 2,
            abs(gripper_to - gripper_from),
            self.pair_lever,
            margin,
            last is not None,
            last_q,
            last_bound,
            beyond,
            reuse_within,
            levels,
            deeper,
            joints.parent,
            joints.placement,
            joints.kind,
            joints.axis,
            joints.coordinate,
            joints.gain,
            self._shape_joint,
            self._local_ends,
            self._local_boxes,
            self._box_half,
            self.radius,
            self.padding,
            self.moving_shapes,
            self.obstacle_low,
            self.obstacle_high,
            self.self_a,
            self.self_b,
            travel,
            reserve,
            start,
            end,
            unproven,
        )
        self.forget_pose()
        return MotionProof(int(outcome), bool(moves), travel, reserve, start, end, unproven.nonzero()[0])

    def forget_pose(self) -> None:
        """A compiled pass posed the coordinates along a motion: the frames and placements no longer match any
        pose() call, and pose() must come before the next measure."""
        self._frames_current = self._pinocchio_current = False

    def _place_geometry(self) -> None:
        if not self._pinocchio_current:
            arm = len(self.kinematics.robot.arm_joints)
            q = self.kinematics.full_q(
                self._coordinates[:arm], self._coordinates[arm] if self.coordinates > arm else 0.0
            )
            pin.forwardKinematics(self.kinematics.model, self.data, q)
            pin.updateGeometryPlacements(self.kinematics.model, self.data, self.geometry, self.geometry_data)
            for rows in self._fixture_rows.values():  # the shared model holds them closed; this copy's own place
                for row in rows:
                    centre = (self.obstacle_low[row] + self.obstacle_high[row]) / 2
                    self.geometry_data.oMg[self._first_obstacle + row] = pin.SE3(np.eye(3), centre)
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

    def object_clearances(
        self, shapes: np.ndarray, solid: coal.ShapeBase, center: np.ndarray, rotation: np.ndarray
    ) -> np.ndarray:
        """coal's clearance of the given shapes from a solid outside the scene (an object's box or cylinder;
        base frame) at the current pose."""
        self._place_geometry()
        placement = coal.Transform3s(rotation, center)
        out = np.empty(len(shapes))
        for row, shape in enumerate(shapes):
            pose = self.geometry_data.oMg[int(shape)]
            out[row] = (
                coal.distance(
                    self.geometry.geometryObjects[int(shape)].geometry,
                    coal.Transform3s(pose.rotation, pose.translation),
                    solid,
                    placement,
                    self._distance_request,
                    coal.DistanceResult(),
                )
                - self.padding[shape]
            )
        return out
