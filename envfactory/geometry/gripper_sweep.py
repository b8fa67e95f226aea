"""Where the fingers can be while the gripper moves, against the scene and the arm, in one pass.

A motion that moves the gripper is judged over every gripper value it may
pass. Measuring each finger with coal at several gripper values costs dozens
of queries per step; but a finger's place relative to the link it is mounted
on depends on the gripper value alone. So each finger's box is tabulated
once, in its mount's frame, at gripper values so close that no point of it is
more than half a millimetre from its place at the nearest of them. At a pose,
the corners of the tabulated boxes across a gripper range, placed by the
mount's frame, are separated from each obstacle box, or from the box around
an arm link's shape, along that box's axes. Less the half millimetre, that is
a lower bound on the finger's clearance at any gripper value in the range;
coal measures only the pairs it leaves in doubt.
"""

from __future__ import annotations

import math

import numpy as np

from envfactory.geometry.kernels.serving import kernels


class GripperSweep:
    """Each finger's box tabulated once in its mount's frame over the gripper's range, and the bound it gives on
    a finger's clearance from an obstacle or an arm link anywhere in a gripper range, at one pose."""

    # no point of a finger's box is farther than this from its place at the nearest tabulated gripper value
    PAD = 0.0005

    def __init__(self, collision):
        self.collision = collision
        gripper = collision.kinematics.robot.gripper
        self.shapes = np.flatnonzero(collision.moved_by_gripper)
        self.row_of = np.full(len(collision.shapes), -1, dtype=np.int64)
        self.row_of[self.shapes] = np.arange(len(self.shapes))
        self.mount_joint = collision.gripper_mount[self.shapes]
        self.low, self.high = (float(gripper.low), float(gripper.high)) if gripper is not None else (0.0, 0.0)
        if not len(self.shapes):
            self.samples, self.spacing = 1, 1.0
            self.corners, self.pad = np.zeros((0, 1, 8, 3)), np.zeros(0)
            return
        # the fastest any corner moves per unit of gripper travel: the structure's one measurement of the fingers
        shapes = collision.shapes
        rate = collision.structure.finger_speeds(
            self.shapes, [shapes[s].corners for s in self.shapes], [0.0] * len(self.shapes)
        )
        self.samples = max(int(np.ceil(rate.max() * (self.high - self.low) / (2 * self.PAD))) + 1, 2)
        values = np.linspace(self.low, self.high, self.samples)
        self.spacing = values[1] - values[0]
        self.corners = self._mounted_corners(values)
        self.pad = rate * self.spacing / 2

    def _mounted_corners(self, values: np.ndarray) -> np.ndarray:
        """(fingers, values, 8, 3): each finger's box corners in its mount joint's frame at each gripper value."""
        shapes = self.collision.shapes
        placements = self.collision.mounted_placements(self.shapes, values)
        out = np.empty((len(self.shapes), len(values), 8, 3))
        for k, per_value in enumerate(placements):
            for row, (shape, relative) in enumerate(zip(self.shapes, per_value)):
                out[row, k] = shapes[shape].corners @ relative.rotation.T + relative.translation
        return out

    def index_pairs(self) -> None:
        """Which measured pairs are a finger against an obstacle or against a shape the gripper does not
        move, and what each is measured against (called whenever the collision model renumbers its pairs)."""
        collision = self.collision
        moved = collision.moved_by_gripper
        finger_a, finger_b = moved[collision.self_a], moved[collision.self_b]
        one_finger = finger_a != finger_b  # two fingers move against each other: the gripper's own design
        self_finger = np.where(finger_a, collision.self_a, collision.self_b)
        self_other = np.where(finger_a, collision.self_b, collision.self_a)
        self.pair_row = np.concatenate(
            [self.row_of[collision.scene_shape], np.where(one_finger, self.row_of[self_finger], -1)]
        )
        self.pair_obstacle = np.concatenate([collision.scene_obstacle, np.full(len(self_other), -1)]).astype(np.int64)
        self.pair_other = np.concatenate([np.full(len(collision.scene_shape), -1), self_other]).astype(np.int64)
        self.pair_other_joint = np.where(self.pair_other >= 0, collision._shape_joint[self.pair_other], 0)
        # the same as plain Python numbers for clearance_one (numpy's scalar indexing would cost more than the bound)
        self._row_of_pair, self._obstacle_of_pair = self.pair_row.tolist(), self.pair_obstacle.tolist()
        self._other_of_pair, self._other_joint_of_pair = self.pair_other.tolist(), self.pair_other_joint.tolist()
        pad = self.pad[np.maximum(self.pair_row, 0)] if len(self.pad) else np.zeros(len(self.pair_row))
        self._pad_of_pair = (np.where(self.pair_row >= 0, pad, 0.0) + collision.pair_padding).tolist()

    def clearance_one(self, pair: int, first: int, last: int) -> float:
        """clearances() for one sweepable pair over the samples first..last (bracket()'s), on scalars."""
        collision = self.collision
        if last < first:
            return -math.inf
        collision._place_frames()
        row = self._row_of_pair[pair]
        return (
            kernels.swept_box_gap(
                collision._frames,
                self.mount_joint,
                self.corners,
                first,
                last,
                row,
                self._obstacle_of_pair[pair],
                collision.obstacle_low,
                collision.obstacle_high,
                self._other_of_pair[pair],
                self._other_joint_of_pair[pair],
                collision._local_corners,
            )
            - self._pad_of_pair[pair]
        )

    def sweepable_one(self, pair: int) -> bool:
        return self._row_of_pair[pair] >= 0

    def sweepable(self, pairs: np.ndarray) -> np.ndarray:
        """Which of these pairs this bound can measure, as a mask."""
        return self.pair_row[pairs] >= 0

    def bracket(self, gripper_from: float, gripper_to: float) -> tuple[int, int]:
        """The first and last tabulated samples that bracket the gripper's range (last < first where the range
        leaves the table: no bound)."""
        low, high = sorted((gripper_from, gripper_to))
        if not len(self.shapes) or low < self.low - 1e-9 or high > self.high + 1e-9:
            return 0, -1
        spacing, top = self.spacing, self.samples - 1
        # scalar arithmetic: this runs thousands of times a second
        first = min(max(math.floor((low - self.low) / spacing + 1e-9), 0), top)
        last = min(max(math.ceil((high - self.low) / spacing - 1e-9), 0), top)
        return first, last

    def clearances(self, pairs: np.ndarray, gripper_from: float, gripper_to: float) -> np.ndarray:
        """A lower bound on each pair's clearance (pairs `sweepable` picks) at the current arm pose, over
        every gripper value between the two."""
        collision = self.collision
        first, last = self.bracket(gripper_from, gripper_to)
        if last < first:
            return np.full(len(pairs), -np.inf)
        collision._place_frames()
        rows = self.pair_row[pairs]
        out = np.empty(len(pairs))
        kernels.swept_box_gaps(
            collision._frames,
            self.mount_joint,
            self.corners,
            first,
            last,
            rows,
            self.pair_obstacle[pairs],
            collision.obstacle_low,
            collision.obstacle_high,
            self.pair_other[pairs],
            self.pair_other_joint[pairs],
            collision._local_corners,
            out,
        )
        return out - self.pad[rows] - collision.pair_padding[pairs]
