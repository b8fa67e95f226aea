"""Keeps the arm from pressing an object that rests on the table with anything but its fingers.

The safety check proves every motion clear of the fixed scene; the task's objects are not part
of it, since the fingers must reach them. But a palm or a wrist commanded into a cube that lies
on the table cannot push it out of the way: the motors press, the cube pushes back, and the arm
is deflected, on a real arm as in the simulator. Measured: a VX300S gripper bar commanded 14 mm
into a resting cube turned the wrist (1 N m) by 0.28 rad and put the bar 0.9 mm into the table
top, a motion the safety check had proven 15 mm clear.

So no motion may end with a non-finger shape inside a resting object, unless it leaves that
shape less deep than it started (a way out after contact). An object held off the table moves
with the gripper and is not guarded. Only the end pose is judged: on its way a shape can sweep
through where the object was and push it along the table, as a push task does.
"""

from __future__ import annotations

import coal
import numpy as np

from envfactory.geometry.collision import CollisionModel
from envfactory.geometry.frames import TaskFrame
from envfactory.geometry.judged_motion import ACCEPTED, Verdict
from envfactory.schema.models import ObjectSpec
from envfactory.step_state import ObjectState


class ObjectPressGuard:
    # An object's underside this close to an obstacle's top rests on it.
    RESTING_WITHIN = 0.005
    # Engines disagree on the same shapes by about a millimetre (PyBullet pads each shape): a
    # shape this close to touching is not pressing.
    CONTACT_TOLERANCE = 0.002
    # A shape already inside an object at the start may end no deeper than this beyond its start.
    DEEPER_TOLERANCE = 0.001

    def __init__(self, collision: CollisionModel, objects: dict[str, ObjectSpec], frame: TaskFrame):
        self.collision = collision
        self.frame = frame
        self.base_in_world = np.asarray(collision.kinematics.robot.mount, float)
        self.guarded = np.array(
            [shape for shape in collision.moving_shapes if not collision.moved_by_gripper[shape]], dtype=int
        )
        self.half_extents = {name: spec.half_extents for name, spec in objects.items()}
        self.shapes = {name: _shape(spec) for name, spec in objects.items()}
        self.surfaces = [
            (o.name, float(o.high[2]), tuple(map(float, o.low[:2])), tuple(map(float, o.high[:2])))
            for o in collision.obstacles
        ]
        self.bounding_radius = {name: spec.bounding_radius for name, spec in objects.items()}

    def check(
        self,
        q_from: np.ndarray,
        q_to: np.ndarray,
        gripper_from: float,
        gripper_to: float,
        objects: dict[str, ObjectState],
    ) -> Verdict:
        for name, state in objects.items():
            center = self.frame.to_world(state.position)
            rotation = self.frame.rotation @ state.rotation if self.frame.rotated else state.rotation
            surface = self._resting_on(center, rotation, self.half_extents[name])
            if surface is None:
                continue
            end = self._clearances(q_to, gripper_to, name, center, rotation)
            if float(end.min()) >= -self.CONTACT_TOLERANCE:
                continue
            start = self._clearances(q_from, gripper_from, name, center, rotation)
            deeper = (end < -self.CONTACT_TOLERANCE) & (end < start - self.DEEPER_TOLERANCE)
            if deeper.any():
                worst = int(np.argmin(np.where(deeper, end, np.inf)))
                link = self.collision.shapes[self.guarded[worst]].link
                return Verdict(
                    False,
                    f"{link} would press the {name} (resting on the {surface}) "
                    f"{-end[worst] * 1000:.0f} mm deep at the end of the motion",
                )
        return ACCEPTED

    def _resting_on(self, center: np.ndarray, rotation: np.ndarray, half: tuple[float, ...]) -> str | None:
        x, y, z = center.tolist()
        underside = z - sum(abs(r) * h for r, h in zip(rotation[2].tolist(), half))  # half: plain floats
        for name, top, low, high in self.surfaces:  # a handful: plain floats beat array calls here
            if abs(underside - top) <= self.RESTING_WITHIN and low[0] <= x <= high[0] and low[1] <= y <= high[1]:
                return name
        return None

    def _clearances(
        self, q_arm: np.ndarray, gripper: float, name: str, center: np.ndarray, rotation: np.ndarray
    ) -> np.ndarray:
        """Each guarded shape's clearance from the object: exact where its capsule reaches the
        object's bounding sphere, the capsule's (a lower bound, positive) elsewhere."""
        collision = self.collision
        collision.pose(np.asarray(q_arm, float), gripper)
        in_base = center - self.base_in_world  # the base frame has the world's axes
        gaps = collision.sphere_gaps(self.guarded, in_base, self.bounding_radius[name])
        near = gaps <= 0.0
        if near.any():
            gaps[near] = collision.object_clearances(self.guarded[near], self.shapes[name], in_base, rotation)
        return gaps


def _shape(spec: ObjectSpec):
    """The object's own shape for coal's distance queries (a cylinder's axis is its z, as in both engines)."""
    radius, _, half_height = spec.half_extents
    if spec.shape == "cylinder":
        return coal.Cylinder(radius, 2 * half_height)
    return coal.Box(*(2 * h for h in spec.half_extents))
