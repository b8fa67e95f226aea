"""Decides whether a joint target may be sent to the arm.

One check serves sim and real: finite values, joint bounds, the largest joint
change allowed in one action, and per-link FK clearance above the floor and
the table top. The motion between the current pose and the target is sampled
too, because two safe end poses can sweep a link through the table.
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
    # Fractions of the commanded motion at which link clearance is checked.
    PATH_SAMPLES = (0.5, 1.0)

    def __init__(self, kinematics: Kinematics, surfaces: Surfaces, settings: SafetySettings):
        self.kinematics = kinematics
        self.surfaces = surfaces
        self.settings = settings

    def link_clearance(self, q_arm: np.ndarray, gripper: float = 0.0) -> np.ndarray:
        points = self.kinematics.checked_link_positions(q_arm, gripper)
        return self.surfaces.clearance(points, self.kinematics.checked_radii, self.settings.table_footprint_margin)

    def pose_is_clear(self, q_arm: np.ndarray, gripper: float = 0.0) -> bool:
        return bool(np.all(self.link_clearance(q_arm, gripper) >= self.settings.surface_margin))

    def path_is_clear(self, q_from: np.ndarray, q_to: np.ndarray, step: float = 0.05) -> Verdict:
        """Clearance along a long joint-space move (a real arm driving home), sampled every `step` rad."""
        q_from, q_to = np.asarray(q_from, float), np.asarray(q_to, float)
        samples = max(2, int(np.ceil(np.max(np.abs(q_to - q_from)) / step)) + 1)
        for fraction in np.linspace(0.0, 1.0, samples):
            clearance = self.link_clearance(q_from + fraction * (q_to - q_from))
            lowest = int(np.argmin(clearance))
            if clearance[lowest] < self.settings.surface_margin:
                link = self.kinematics.frame_names([self.kinematics.checked_frames[lowest]])[0]
                return Verdict(False, f"link {link} would come within {clearance[lowest]:.3f} m of a surface "
                                      f"at {fraction:.0%} of the way")
        return ACCEPTED

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
        # the end pose first: when it clears the highest surface by more than any point can move in
        # half the motion, the midpoint is clear too and needs no second FK pass
        for fraction in sorted(self.PATH_SAMPLES, reverse=True):
            points = kin.checked_link_positions(q_arm_now + fraction * delta, gripper)
            clearance = self.surfaces.clearance(points, kin.checked_radii, self.settings.table_footprint_margin)
            lowest = int(np.argmin(clearance))
            if clearance[lowest] < self.settings.surface_margin:
                link = kin.frame_names([kin.checked_frames[lowest]])[0]
                return Verdict(False, f"link {link} would come within {clearance[lowest]:.3f} m of a surface")
            if fraction == 1.0 and self._rest_is_clear(points, delta, 1.0 - min(self.PATH_SAMPLES)):
                break
        return ACCEPTED

    def _rest_is_clear(self, points: np.ndarray, delta: np.ndarray, span: float) -> bool:
        """Whether poses within `span` of this motion from `points` must clear every surface.

        No point moves farther than `travel`: it drops at most that much, and it can only come
        over the table if it is within that much of the table's footprint already."""
        travel = self.kinematics.lever_arm * float(np.sum(np.abs(delta))) * span
        clearance = self.surfaces.clearance(points, self.kinematics.checked_radii,
                                            self.settings.table_footprint_margin + travel)
        return float(np.min(clearance)) - travel >= self.settings.surface_margin
