"""Proof that a commanded motion keeps the robot's moving shapes away from the movable objects.

Both engines play a motion proven clear this way without dynamics: nothing can touch the objects, so the
substeps would only reproduce what the joint targets already say. The shapes are the safety check's own."""

from __future__ import annotations

import numpy as np

from envfactory.geometry.collision import CollisionModel, capsule_sphere_gaps

# Closer than this to a movable object, a motion gets full dynamics. Bullet builds contact points
# within its 2 cm breaking threshold but pushes only on a gap closed within one substep (a few mm
# at the arm's top speed); MuJoCo pushes on touch. 1 cm keeps every kinematic motion clear of both.
NEAR_CONTACT = 0.01


def bounding_radius(cube_size: float) -> float:
    """The radius of the sphere around a cube of this edge: what the proofs keep the robot away from."""
    return cube_size * np.sqrt(3) / 2


class ObjectClearance:
    """Lower bounds on the gap between the arm's moving collision shapes and a sphere, over a motion.

    The shapes are the safety check's own (the capsule fitted around each URDF collision shape,
    and its lever arms per coordinate), posed by its compiled forward kinematics."""

    # the finest piece of a motion the proof looks at: finer pieces would cost more than the substeps
    MIN_PIECE = 1.0 / 8

    def __init__(self, collision: CollisionModel):
        kinematics = collision.kinematics
        self.collision = collision
        self.moving = collision.moving_shapes
        self.radius = collision.radius[self.moving]
        self.lever = collision.lever[self.moving]
        self.arm = len(kinematics.robot.arm_joints)
        self.base_in_world = np.asarray(kinematics.robot.mount, float)

    def gaps(self, q_arm: np.ndarray, gripper: float, centers: np.ndarray, radii: np.ndarray) -> np.ndarray:
        """(shapes, spheres) lower bounds on the gap at one pose; sphere centres in the world frame."""
        # the safety check's own compiled frames and capsules: one forward kinematics for both
        self.collision.pose(q_arm, gripper)
        ends = self.collision.capsule_ends()[self.moving]
        # base frame: the mount is a translation
        return capsule_sphere_gaps(ends, self.radius, centers - self.base_in_world, radii)

    def motion_is_clear(self, q_from, gripper_from, q_to, gripper_to, centers, radii, margin: float) -> bool:
        """Whether every moving shape stays `margin` from every sphere while the arm moves along the
        straight joint-space line from q_from to q_to (the motors' path: every joint lands on its
        target at the same time) and the gripper anywhere between its two values. Pieces of the line
        whose two end bounds cannot prove it are halved, down to MIN_PIECE."""
        q_from, q_to = np.asarray(q_from, float), np.asarray(q_to, float)
        arm_travel = (self.lever[:, :self.arm] @ np.abs(q_to - q_from))[:, None]
        gripper_middle, reserve = gripper_from, np.zeros((len(self.radius), 1))
        if self.lever.shape[1] > self.arm:
            # every pose is judged over the gripper's whole range: its middle, less half its sweep
            gripper_middle = (gripper_from + gripper_to) / 2
            reserve = (self.lever[:, self.arm] * abs(gripper_to - gripper_from) / 2)[:, None]

        def bound(fraction: float) -> np.ndarray:
            return self.gaps(q_from + fraction * (q_to - q_from), gripper_middle, centers, radii) - reserve

        start = bound(0.0)
        if np.all(start - arm_travel >= margin):
            return True
        pieces = [(0.0, start, 1.0, bound(1.0))]
        while pieces:
            a, bound_a, b, bound_b = pieces.pop()
            # a point that moved s from one end is at most travel - s from the other
            if np.all(bound_a + bound_b - arm_travel * (b - a) >= 2 * margin):
                continue
            if b - a <= self.MIN_PIECE:
                return False
            middle = (a + b) / 2
            bound_m = bound(middle)
            if np.any(bound_m < margin):
                return False
            pieces += [(a, bound_a, middle, bound_m), (middle, bound_m, b, bound_b)]
        return True
