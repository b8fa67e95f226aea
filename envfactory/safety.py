"""Decides whether a joint target may be sent to the arm.

One check serves sim and real: finite values, joint bounds, the largest joint
change allowed in one action, and per-link FK clearance above the floor and
the table top. The motion between the current pose and the target is proven
clear as a whole, not sampled, because two safe end poses can sweep a link
through the table between any two samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from envfactory.kinematics import Kinematics
from envfactory.spec.schema import SafetySettings, TableSpec


@dataclass(frozen=True)
class Verdict:
    accepted: bool
    reason: str = ""


ACCEPTED = Verdict(True)


@dataclass(frozen=True)
class Surfaces:
    """The floor and the table top, in the task frame."""

    floor_z: float
    table_min_xy: np.ndarray
    table_max_xy: np.ndarray
    table_top_z: float

    @classmethod
    def from_scene(cls, table: TableSpec, floor_z_world: float, task_origin_world: np.ndarray) -> "Surfaces":
        half = np.asarray(table.size) / 2.0
        center = np.asarray(table.center) - task_origin_world[:2]
        return cls(
            floor_z=floor_z_world - task_origin_world[2],
            table_min_xy=center - half,
            table_max_xy=center + half,
            table_top_z=table.top_z - task_origin_world[2],
        )

    def clearance(self, points: np.ndarray, radii: np.ndarray, footprint_margin: float) -> np.ndarray:
        """Height of each sphere's bottom above the surface below it."""
        reach = footprint_margin + radii
        x, y = points[:, 0], points[:, 1]
        (x_min, y_min), (x_max, y_max) = self.table_min_xy, self.table_max_xy
        over_table = (x >= x_min - reach) & (x <= x_max + reach) & (y >= y_min - reach) & (y <= y_max + reach)
        surface = np.where(over_table, self.table_top_z, self.floor_z)
        return points[:, 2] - radii - surface


class SafetyCheck:
    # Bisection of the commanded motion stops at pieces this small; a piece that still cannot be
    # proven clear is refused: a doubt stops the arm.
    FINEST_PIECE = 1.0 / 64

    def __init__(self, kinematics: Kinematics, surfaces: Surfaces, settings: SafetySettings):
        self.kinematics = kinematics
        self.surfaces = surfaces
        self.settings = settings

    def link_clearance(self, q_arm: np.ndarray, gripper: float = 0.0) -> np.ndarray:
        points = self.kinematics.checked_link_positions(q_arm, gripper)
        return self.surfaces.clearance(points, self.kinematics.checked_radii, self.settings.table_footprint_margin)

    def pose_is_clear(self, q_arm: np.ndarray, gripper: float = 0.0) -> bool:
        return bool(np.all(self.link_clearance(q_arm, gripper) >= self.settings.surface_margin))

    def path_is_clear(self, q_from: np.ndarray, q_to: np.ndarray) -> Verdict:
        """Clearance along a long joint-space move (a real arm driving home), with no joint-change limit."""
        q_from, q_to = np.asarray(q_from, float), np.asarray(q_to, float)
        verdict = self._pose_verdict(q_to, 0.0, " at the end of the way")
        if not verdict.accepted:
            return verdict
        return self._motion_verdict(q_from, q_to - q_from, 0.0, finest=self.FINEST_PIECE / 16)

    def check(self, q_arm_now: np.ndarray, q_arm_target: np.ndarray, gripper: float = 0.0) -> Verdict:
        if not np.all(np.isfinite(q_arm_target)):
            return Verdict(False, "non-finite joint target")
        kin = self.kinematics
        if ((q_arm_target < kin.arm_lower) | (q_arm_target > kin.arm_upper)).any():
            return Verdict(False, "joint target outside the joint bounds")
        delta = q_arm_target - q_arm_now
        largest = float(np.max(np.abs(delta)))
        if largest > self.settings.max_joint_delta + 1e-12:
            return Verdict(False, f"joint change {largest:.3f} rad exceeds max_joint_delta {self.settings.max_joint_delta}")
        end = self.kinematics.checked_link_positions(q_arm_target, gripper)
        verdict = self._points_verdict(end)
        if not verdict.accepted:
            return verdict
        travel = self.kinematics.lever_arm * float(np.sum(np.abs(delta)))
        if self._vouches(end, travel):  # well clear of everything: the end vouches for the whole motion
            return ACCEPTED
        return self._motion_verdict(q_arm_now, delta, gripper)

    def _pose_verdict(self, q_arm: np.ndarray, gripper: float, where: str = "") -> Verdict:
        """Whether one pose clears the surfaces, naming the offending link if not."""
        return self._points_verdict(self.kinematics.checked_link_positions(q_arm, gripper), where)

    def _points_verdict(self, points: np.ndarray, where: str = "") -> Verdict:
        clearance = self.surfaces.clearance(points, self.kinematics.checked_radii, self.settings.table_footprint_margin)
        lowest = int(np.argmin(clearance))
        if clearance[lowest] < self.settings.surface_margin:
            link = self.kinematics.frame_names([self.kinematics.checked_frames[lowest]])[0]
            return Verdict(False, f"link {link} would come within {clearance[lowest]:.3f} m of a surface{where}")
        return ACCEPTED

    def _vouches(self, points: np.ndarray, travel: float) -> bool:
        """Whether every pose whose points lie within `travel` of these clears the surfaces:
        a point drops at most `travel`, and comes over the table only from within `travel` of it."""
        clearance = self.surfaces.clearance(points, self.kinematics.checked_radii,
                                            self.settings.table_footprint_margin + travel)
        return float(np.min(clearance)) - travel >= self.settings.surface_margin

    def _motion_verdict(self, q_start: np.ndarray, delta: np.ndarray, gripper: float,
                        finest: float = FINEST_PIECE) -> Verdict:
        """Prove every pose between start and target clear, not just sampled ones.

        No checked point moves farther than lever_arm · Σ|Δq| · (fraction of the motion), so a
        pose whose clearance beats the margin by that travel (against a table footprint widened
        by the same travel) vouches for its whole neighbourhood. Pieces it cannot vouch for are
        halved until they are proven, found unsafe, or too small: then the motion is refused."""
        per_fraction = self.kinematics.lever_arm * float(np.sum(np.abs(delta)))
        pieces = [(0.0, 1.0)]
        while pieces:
            low, high = pieces.pop()
            middle, half = (low + high) / 2, (high - low) / 2
            points = self.kinematics.checked_link_positions(q_start + middle * delta, gripper)
            if self._vouches(points, per_fraction * half):
                continue
            verdict = self._points_verdict(points, f" at {middle:.0%} of the motion")
            if not verdict.accepted:
                return verdict
            if half * 2 <= finest:
                if low == 0.0 and not self.pose_is_clear(q_start, gripper):
                    continue  # already inside the margin (contact, tracking error): a way out is not refused
                return Verdict(False, f"cannot prove the motion clears the surfaces near {middle:.0%} of the way")
            pieces += [(low, middle), (middle, high)]
        return ACCEPTED
