"""What a robot's collision shapes are to one another, read off the kinematic tree once: which coordinates move
each shape, its levers (how far any point of it can move per unit change of each coordinate, the bound the
safety proof rests on), the joint each finger is mounted on, the self pairs the structure itself exempts, and
the fingers' speed per unit of gripper travel, measured once on a dense sweep of the gripper's range for both
the capsule levers and the gripper sweep's table."""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin

from envfactory.geometry.collision.shapes import Shape, revolute_axis
from envfactory.geometry.kinematics import Kinematics

# The gripper's range is swept at this many values; each measured speed is grown by this factor (the sweep
# samples a smooth linkage densely, so a point's fastest speed between samples stays within it)
GRIPPER_SAMPLES = 401
GRIPPER_SAFETY_FACTOR = 1.25


def _turning_angles(rotations: np.ndarray) -> np.ndarray:
    """The angle turned between consecutive rotations (the norm of log3 of each relative rotation), by atan2 of
    its sine and cosine parts, which keeps small angles exact where arccos of the trace would not."""
    relative = rotations[1:] @ np.swapaxes(rotations[:-1], 1, 2)
    sine_axis = np.stack(
        [
            relative[:, 2, 1] - relative[:, 1, 2],
            relative[:, 0, 2] - relative[:, 2, 0],
            relative[:, 1, 0] - relative[:, 0, 1],
        ],
        axis=1,
    )
    cosine = (np.trace(relative, axis1=1, axis2=2) - 1.0) / 2.0
    return np.arctan2(np.linalg.norm(sine_axis, axis=1) / 2.0, cosine)


class Structure:
    """The structure of one robot's shapes (built once per robot with its CollisionModel, never changed)."""

    def __init__(self, kinematics: Kinematics, geometry, shapes: list[Shape]):
        self.kinematics, self.geometry, self.shapes = kinematics, geometry, shapes
        drivers = self.drivers = kinematics.coordinate_drivers()
        self.coordinates = len(kinematics.robot.arm_joints) + (kinematics.robot.gripper is not None)
        self.moved = [self._is_moved(shape.joint, drivers) for shape in shapes]
        # the fingers: shapes the gripper moves (the rest of the arm holds still when only the gripper moves)
        gripper = self.coordinates - 1 if kinematics.robot.gripper is not None else None
        self.moved_by_gripper = np.array(
            [gripper is not None and self._is_moved(shape.joint, drivers, gripper) for shape in shapes], dtype=bool
        )
        self.lever = np.array([self._lever(shape, drivers) for shape in shapes])  # (shapes, coordinates)
        # per shape, the nearest joint at or above it that the gripper does not move
        self.gripper_mount = np.array([self._gripper_mount(shape.joint, drivers) for shape in shapes], dtype=np.int64)
        self._sweep: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._relative_levers: dict[tuple[int, int], np.ndarray] = {}
        self._levers_above: dict[tuple[int, int], np.ndarray] = {}
        if kinematics.robot.gripper is not None:
            # a shape the gripper does not move has no gripper lever (the measured sweep leaves rounding noise)
            ends = [np.array([shape.capsule_start, shape.capsule_end]) for shape in shapes]
            speeds = self.finger_speeds(range(len(shapes)), ends, [shape.radius for shape in shapes])
            self.lever[:, -1] = np.where(self.moved_by_gripper, speeds, 0.0)

    def exemption(self, a: int, b: int) -> str:
        """Why the self pair (a, b) needs no check by the structure alone, or ""."""
        return self._structural_exemption(a, b, self.drivers)

    def relative_lever(self, a: int, b: int) -> np.ndarray:
        """The levers of shapes a and b against each other (kept: a model measures its pairs with every pair
        first, then again with the pair list's)."""
        lever = self._relative_levers.get((a, b))
        if lever is None:
            lever = self._relative_levers[(a, b)] = self._relative_lever(a, b, self.drivers)
            lever.flags.writeable = False
        return lever

    def finger_speeds(self, shapes, points: list[np.ndarray], radii: list[float]) -> np.ndarray:
        """The fastest any point of each shape moves per unit of gripper travel, times the safety factor: each
        shape's `points` (in its joint's frame) and, for a capsule, `radii` times its turning rate, measured over
        the gripper's range on one dense sweep shared by every caller. A linkage's joints turn against each
        other (a parallel gripper keeps its pads upright), so the summed joint levers would overstate the motion
        several times; the measured sweep bounds it instead."""
        values, rotations, translations = self._dense_sweep()
        step = values[1] - values[0]
        rates = np.zeros(len(points))
        for row, shape in enumerate(shapes):
            local = np.asarray(points[row], float).reshape(-1, 3)
            placed = rotations[:, shape] @ local.T + translations[:, shape, :, None]  # sample, xyz, point
            moved = np.linalg.norm(np.diff(placed, axis=0), axis=1).max(axis=1)
            turned = _turning_angles(rotations[:, shape]) if radii[row] else 0.0
            rates[row] = GRIPPER_SAFETY_FACTOR * max(0.0, np.max((moved + radii[row] * turned) / step))
        return rates

    def _dense_sweep(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The gripper values of the dense sweep and every shape's mounted placement at each, as rotations
        (sample, shape, 3, 3) and translations (sample, shape, 3) for whole-sweep arithmetic (computed once)."""
        if self._sweep is None:
            gripper = self.kinematics.robot.gripper
            values = np.linspace(gripper.low, gripper.high, GRIPPER_SAMPLES)
            shape_joints = np.array([shape.joint for shape in self.shapes], dtype=np.int64)
            # each joint's world frame at every sample, read once (shapes share joints), then the mounted placement
            # M_mount⁻¹ · M_joint of every shape over the whole sweep at once: a Python call per shape and sample
            # cost most of a first make
            joints = np.union1d(shape_joints, self.gripper_mount)
            column = {int(joint): k for k, joint in enumerate(joints)}
            world_rotations, world_translations = self._joint_frames(values, joints)
            shape_column = [column[int(joint)] for joint in shape_joints]
            mount_column = [column[int(joint)] for joint in self.gripper_mount]
            mount_rotations_t = np.swapaxes(world_rotations[:, mount_column], -1, -2)
            rotations = mount_rotations_t @ world_rotations[:, shape_column]
            offsets = world_translations[:, shape_column] - world_translations[:, mount_column]
            translations = (mount_rotations_t @ offsets[..., None])[..., 0]
            self._sweep = values, rotations, translations
        return self._sweep

    def _joint_frames(self, values: np.ndarray, joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """These joints' world rotations (sample, joint, 3, 3) and translations (sample, joint, 3) at each gripper
        value, the arm at zero (the gripper alone moves the mounted placements)."""
        kin, model = self.kinematics, self.kinematics.model
        data = model.createData()
        q_arm = np.zeros(len(kin.robot.arm_joints))
        rotations = np.empty((len(values), len(joints), 3, 3))
        translations = np.empty((len(values), len(joints), 3))
        columns = list(enumerate(joints.tolist()))
        for sample, value in enumerate(values):
            pin.forwardKinematics(model, data, kin.full_q(q_arm, value))
            for k, joint in columns:
                placement = data.oMi[joint]
                rotations[sample, k] = placement.rotation
                translations[sample, k] = placement.translation
        return rotations, translations

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

    def _lever_above(self, shape: int, above: int) -> np.ndarray:
        """Shape `shape`'s levers relative to joint `above`, kept: the pairs of one shape share most of them."""
        lever = self._levers_above.get((shape, above))
        if lever is None:
            lever = self._levers_above[(shape, above)] = self._lever(self.shapes[shape], self.drivers, above)
        return lever

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
                axis = revolute_axis(model.joints[joint])
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
                travel = max(
                    abs(model.lowerPositionLimit[model.idx_qs[joint]]),
                    abs(model.upperPositionLimit[model.idx_qs[joint]]),
                )
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
            levers.append(self._lever_above(other, below if below is not None else common))
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
        axis = revolute_axis(model.joints[joint])
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
