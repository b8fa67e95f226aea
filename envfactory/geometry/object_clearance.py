"""Proof that a commanded motion keeps the robot's moving shapes away from the movable objects.

Both engines play a motion proven clear this way without dynamics: nothing can touch the objects, so the
substeps would only reproduce what the joint targets already say. The shapes are the safety check's own."""

from __future__ import annotations

import numpy as np

from envfactory.geometry.collision import CollisionModel
from envfactory.geometry.kernels.serving import kernels

# Closer than this to a movable object, a motion gets full dynamics. Bullet builds contact points
# within its 2 cm breaking threshold but pushes only on a gap closed within one substep (a few mm
# at the arm's top speed); MuJoCo pushes on touch. 1 cm keeps every kinematic motion clear of both.
NEAR_CONTACT = 0.01


class ObjectClearance:
    """Lower bounds on the gap between the arm's moving collision shapes and a sphere, over a motion.

    The shapes are the safety check's own (the capsule fitted around each URDF collision shape,
    and its lever arms per coordinate), posed by its compiled forward kinematics."""

    # the finest piece of a motion the proof looks at (2**-LEVELS): finer pieces would cost more than the substeps
    LEVELS = 3

    def __init__(self, collision: CollisionModel):
        kinematics = collision.kinematics
        self.collision = collision
        self.moving = collision.moving_shapes
        self.lever = collision.lever[self.moving]
        self.arm = len(kinematics.robot.arm_joints)
        self.base_in_world = np.asarray(kinematics.robot.mount, float)

    def motion_is_clear(self, q_from, gripper_from, q_to, gripper_to, centers, radii, margin: float) -> bool:
        """Whether every moving shape stays `margin` from every sphere while the arm moves along the
        straight joint-space line from q_from to q_to (the motors' path: every joint lands on its
        target at the same time) and the gripper anywhere between its two values. Pieces of the line
        whose two end bounds cannot prove it are halved, down to 2**-LEVELS of it (one compiled pass:
        motion_clear_of_spheres)."""
        collision = self.collision
        q_from = np.asarray(q_from, float)
        coordinates = collision._coordinates
        if self.lever.shape[1] > self.arm:
            # every pose is judged over the gripper's whole range: its middle, less half its sweep (the reserve)
            coordinates[self.arm] = (gripper_from + gripper_to) / 2
        joints = collision._joints
        clear = kernels.motion_clear_of_spheres(
            coordinates,
            q_from,
            np.asarray(q_to, float) - q_from,
            joints.parent,
            joints.placement,
            joints.kind,
            joints.axis,
            joints.coordinate,
            joints.gain,
            collision._shape_joint,
            collision._local_ends,
            self.moving,
            collision.radius,
            self.lever,
            abs(gripper_to - gripper_from),
            np.asarray(centers, float),
            self.base_in_world,
            np.asarray(radii, float),
            float(margin),
            self.LEVELS,
        )
        collision.forget_pose()  # the kernel posed its coordinates along the motion
        return bool(clear)
