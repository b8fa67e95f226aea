"""A held object rides with the hand: a carry that needs no dynamics.

An object squeezed between both pads, touching nothing else, that did not slip against the hand over the last
simulated cycle moves as part of the hand while the arm's motion is proven to keep it NEAR_CONTACT away from
every fixed obstacle and every other object, and asks no more of the grasp than a simulated cycle of this
grasp already held: the peak specific force the pads must supply by friction (the object's acceleration less
gravity, in the plane of the pads) along the commanded profile. Anything else (a release, a gripper still on
its way, another contact, a slip, a harder motion, a motion the proof cannot clear) returns the cycle to full
dynamics, and a grasp proven under the harder motion may carry it next time.

The proof is the lever bound of the safety check, for a point fixed to the hand: moving joint i by dq_i moves
the point at most |dq_i| times its distance from joint i's axis, and that distance is at most the fixed
lengths between the anchors of joints i, i+1, …, n plus the point's distance from the last anchor (the
triangle inequality; each is constant whatever the pose). Pieces of the straight joint-space line whose end
gaps cannot prove it are halved down to MIN_PIECE.
"""

from __future__ import annotations

import mujoco
import numpy as np

from envfactory.geometry.object_clearance import NEAR_CONTACT
from envfactory.geometry.obstacles import Obstacle
from envfactory.geometry.timing_law import quintic

# The held object moved less than this against the hand over the last simulated cycle, m: a grasp that holds
# (MuJoCo's no-slip pass leaves a squeezed cube still to well under this; a cube on its way out moves mm).
HOLD_SLIP = 5e-4
MIN_PIECE = 1.0 / 16
# Samples of the profile's timing law at which the held point's acceleration is taken (second differences)
DEMAND_SAMPLES = 11
GRAVITY = np.array([0.0, 0.0, -9.81])


def _pose(data, body: int) -> tuple[np.ndarray, np.ndarray]:
    return data.xpos[body].copy(), data.xmat[body].reshape(3, 3).copy()


def box_gaps(point: np.ndarray, centers: np.ndarray, halves: np.ndarray) -> np.ndarray:
    """Distance from a point to each axis-aligned box (0 inside)."""
    return np.linalg.norm(np.maximum(np.abs(point - centers) - halves, 0.0), axis=1)


class Carry:
    """Decides whether a cycle may carry a held object without dynamics, and plays it."""

    def __init__(self, model, handles, pad_bodies: set[int], obstacles: list[Obstacle], radii: dict[str, float]):
        self.model, self.handles = model, handles
        self.pad_bodies = pad_bodies
        self.box_centers = np.array([o.center for o in obstacles])
        self.box_halves = np.array([o.half_extents for o in obstacles])
        self.radii = radii
        arm_joints = [int(model.dof_jntid[dof]) for dof in handles.arm_dof]
        self.arm_joints = arm_joints
        self.hand = int(model.jnt_bodyid[arm_joints[-1]])  # the last arm joint's body carries the gripper
        self.object_geom = {name: int(model.body_geomadr[body]) for name, body in handles.object_body.items()}
        self._scratch = mujoco.MjData(model)
        self._relative: dict[str, tuple[np.ndarray, np.ndarray]] = {}  # object pose in the hand, last cycle end
        self.slip: dict[str, float] = {}  # how far each object moved against the hand over the last cycle, m
        self.withstood: dict[str, float] = {}  # the hardest demand (m/s^2) the present grasp held, simulated
        self._pads = sorted(self.pad_bodies)

    def reset(self) -> None:
        self._relative.clear()
        self.slip.clear()
        self.withstood.clear()

    def measure(self, data, q_from: np.ndarray, q_to: np.ndarray, length: float) -> None:
        """At the end of a simulated cycle that moved the arm from q_from to q_to over `length` s: each object's
        slip against the hand since the last cycle, and what its grasp has withstood."""
        hand_position, hand_rotation = _pose(data, self.hand)
        for name, body in self.handles.object_body.items():
            position = hand_rotation.T @ (data.xpos[body] - hand_position)
            rotation = hand_rotation.T @ data.xmat[body].reshape(3, 3)
            if name in self._relative:
                self.slip[name] = float(np.linalg.norm(position - self._relative[name][0]))
            self._relative[name] = (position, rotation)
        name = self.held(data)
        for other in self.handles.object_body:
            if other != name:
                self.withstood.pop(other, None)  # not held (any more): a new grasp proves itself anew
        if name is not None:
            self.withstood[name] = max(self.withstood.get(name, 0.0), self.demand(data, name, q_from, q_to, length))

    def demand(self, data, name: str, q_from: np.ndarray, q_to: np.ndarray, length: float) -> float:
        """The peak specific force (m/s^2) the pads must supply by friction to keep the object in the hand along
        the profile from q_from to q_to: its acceleration less gravity, in the plane of the pads."""
        relative_position = self._relative[name][0]
        pad_normal = self._pad_normal(data)
        tau = np.linspace(0.0, 1.0, DEMAND_SAMPLES)
        points, normals = [], []
        for fraction in quintic(tau):
            hand_position, hand_rotation = self._hand_at(data, q_from + fraction * (q_to - q_from))
            points.append(hand_position + hand_rotation @ relative_position)
            normals.append(hand_rotation @ pad_normal)
        step = max(length, 1e-6) / (DEMAND_SAMPLES - 1)
        points = np.array(points)
        acceleration = (points[2:] - 2 * points[1:-1] + points[:-2]) / step**2
        force = acceleration - GRAVITY
        normals = np.array(normals[1:-1])
        in_plane = force - np.sum(force * normals, axis=1, keepdims=True) * normals
        return float(np.max(np.linalg.norm(in_plane, axis=1)))

    def _pad_normal(self, data) -> np.ndarray:
        """The pads' closing direction in the hand frame, as the gripper is now (zero without two pads)."""
        if len(self._pads) < 2:
            return np.zeros(3)
        hand_rotation = data.xmat[self.hand].reshape(3, 3)
        between = hand_rotation.T @ (data.xpos[self._pads[0]] - data.xpos[self._pads[1]])
        return between / max(np.linalg.norm(between), 1e-9)

    def _hand_at(self, data, q_arm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        scratch = self._scratch
        scratch.qpos[:] = data.qpos
        scratch.qpos[self.handles.arm_qpos] = q_arm
        mujoco.mj_kinematics(self.model, scratch)
        return _pose(scratch, self.hand)

    def held(self, data) -> str | None:
        """The object held in a stable grasp, if one is."""
        for name, geom in self.object_geom.items():
            if self.slip.get(name, np.inf) >= HOLD_SLIP:
                continue
            touching = set()
            for index in range(data.ncon):
                contact = data.contact[index]
                if geom not in (contact.geom1, contact.geom2):
                    continue
                other = contact.geom2 if contact.geom1 == geom else contact.geom1
                touching.add(int(self.model.geom_bodyid[other]))
            if touching == self.pad_bodies:
                return name
        return None

    def plan(self, data, name: str, q_from: np.ndarray, q_to: np.ndarray, length: float):
        """The object's world pose at q_to if the carry from q_from asks no more of the grasp than it withstood
        and is proven clear, else None."""
        if self.demand(data, name, q_from, q_to, length) > self.withstood.get(name, 0.0):
            return None
        handles = self.handles
        radius = self.radii[name]
        others = [
            (data.xpos[body].copy(), self.radii[other]) for other, body in handles.object_body.items() if other != name
        ]
        relative_position, relative_rotation = self._relative[name]
        # lever arms of the held object's centre about each arm joint, valid in every pose (module docstring)
        anchors = data.xanchor[self.arm_joints]
        links = np.linalg.norm(np.diff(anchors, axis=0), axis=1)
        tail = np.concatenate([np.cumsum(links[::-1])[::-1], [0.0]])
        center = data.xpos[handles.object_body[name]]
        lever = tail + np.linalg.norm(center - anchors[-1])
        travel = float(lever @ np.abs(q_to - q_from))

        def gap(fraction: float) -> tuple[float, np.ndarray, np.ndarray]:
            hand_position, hand_rotation = self._hand_at(data, q_from + fraction * (q_to - q_from))
            point = hand_position + hand_rotation @ relative_position
            gaps = list(box_gaps(point, self.box_centers, self.box_halves) - radius)
            gaps += [np.linalg.norm(point - other) - radius - other_radius for other, other_radius in others]
            return min(gaps), point, hand_rotation @ relative_rotation

        start, _, _ = gap(0.0)
        end, point, rotation = gap(1.0)
        pieces = [(0.0, start, 1.0, end)]
        while pieces:
            a, gap_a, b, gap_b = pieces.pop()
            if gap_a < NEAR_CONTACT or gap_b < NEAR_CONTACT:
                return None
            # a point that moved s from one end is at most travel - s from the other
            if gap_a + gap_b - travel * (b - a) >= 2 * NEAR_CONTACT:
                continue
            if b - a <= MIN_PIECE:
                return None
            middle = (a + b) / 2
            gap_m = gap(middle)[0]
            pieces += [(a, gap_a, middle, gap_m), (middle, gap_m, b, gap_b)]
        return point, rotation
