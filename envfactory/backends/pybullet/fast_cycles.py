"""Physics only where it matters: the `sim.fidelity: fast` stepping of an action cycle.

The reference pages' step is a joint target the arm reaches within `action_speed`, the
observation read at the end of `action_cycle_time`. Out of contact the
position motors land every joint on its target to within microradians, so
simulating the cycle only reproduces what is known in advance. A cycle is
therefore played one of three ways:

- kinematic: the arm is set on its target and the gripper where its motor's
  recorded response takes it in one cycle, without a substep. Only when every
  movable object is at rest and the whole commanded motion of the arm's moving
  shapes and the gripper is proven to stay NEAR_CONTACT away from each object's
  bounding sphere (the lever bound of envfactory/geometry/safety.py: no point of a shape
  moves farther than its lever arms times the joint changes). An object not yet
  seen at rest (fresh from a reset) gets one substep first to show it rests;
- at rest: nothing is commanded to change and nothing moved when the last
  cycle ended: no substeps either;
- dynamic: the full substeps, ended early once arm, gripper and objects are
  at rest after the commanded motion is over. Near contact, with an object in
  motion, or whenever a condition above is in doubt.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass
from typing import Callable

import numpy as np
import pybullet as p

from envfactory.backends.at_rest import GRIPPER_REST, JOINT_REST, OBJECT_REST, OBJECT_SPIN_REST, CycleCounts
from envfactory.backends.synchronous import synchronous_length
from envfactory.geometry.object_clearance import NEAR_CONTACT, ObjectClearance

# After `action_speed` the position motors close the rest of a motion by a factor e about every 9
# substeps (measured at 240 Hz: 1e-2 rad short at 0.2 s, 5e-6 rad at 0.5 s). A cycle with fewer
# substeps than this after the motion ends is not over when the observation is read: it gets dynamics.
SETTLE_SUBSTEPS = 60
# A motion that starts or ends this close to a joint's limit (rad) gets dynamics: PyBullet's limit constraint and
# the motor together leave the joint up to 2 mrad from its target there (measured on a shoulder whose spec bound lies
# just beyond its URDF limit: 1.8 mrad, 1 mm at the EE), where the kinematic cycle would land it exactly.
NEAR_LIMIT = 0.005
# A joint this close to its target (rad, or m for a finger) counts as there: holding it still
# moves it less than this in full dynamics.
SETTLED = 1e-4
# The at-rest test runs every this many substeps once the commanded motion is over.
REST_CHECK_EVERY = 4


class GripperResponse:
    """The gripper motor's step response, recorded once in the simulator: how far from its target
    the gripper is n substeps after a command from rest, in each direction. A command of size e
    starts where the curve is e away and runs along it; position motors with a speed limit
    respond the same way to every step of their range (speed-limited, then a common tail)."""

    def __init__(self, closing, opening, dt: float):
        # per direction, the error to the target per substep (decreasing), the rate per substep, and the error
        # negated (rising, for bisect), as plain lists: read a substep at a time, numpy's scalar calls would cost
        # more than the reading
        self._lists = {
            direction: (curve.tolist(), (-np.diff(curve)).tolist(), (-curve).tolist())
            for direction, curve in ((1.0, np.asarray(closing, float)), (-1.0, np.asarray(opening, float)))
        }
        self.dt = dt

    def curves(self) -> tuple[list[float], list[float]]:
        """(closing, opening): the recorded errors to the target, a substep apart, as the constructor takes them."""
        return self._lists[1.0][0], self._lists[-1.0][0]

    def advance(self, value: float, target: float, substeps: int) -> tuple[float, float] | None:
        """Position and velocity after `substeps`, or None if the command is outside the recorded range."""
        error = target - value
        if abs(error) < 1e-9:
            return target, 0.0
        direction = 1.0 if error > 0 else -1.0
        curve, rates, rising = self._lists[direction]
        if abs(error) > curve[0] + 1e-6:
            return None
        # the substep (fractional) at which the recorded response is this far from its target
        start = _at_value(rising, -abs(error))
        end = start + substeps
        if end >= len(curve) - 1:
            return target - direction * curve[-1], 0.0
        remaining = _at_index(curve, end)
        speed = _at_index(rates, end - 0.5) / self.dt  # each rate belongs to the middle of its substep
        return target - direction * remaining, direction * speed


def _at_index(values: list[float], index: float) -> float:
    """values read at a fractional index, linearly between neighbours and held at both ends."""
    if index <= 0.0:
        return values[0]
    whole = int(index)
    if whole >= len(values) - 1:
        return values[-1]
    share = index - whole
    return values[whole] + share * (values[whole + 1] - values[whole])


def _at_value(rising: list[float], value: float) -> float:
    """The fractional index at which a non-decreasing list reaches `value`, linearly between neighbours."""
    after = bisect.bisect_left(rising, value)
    if after == 0:
        return 0.0
    if after >= len(rising):
        return float(len(rising) - 1)
    low, high = rising[after - 1], rising[after]
    return after - 1 + ((value - low) / (high - low) if high > low else 1.0)


def record_gripper_response(
    client: int, body: int, joint: int, open_value: float, closed_value: float, dt: float, drive, limit_s: float = 5.0
) -> GripperResponse:
    """Drive the gripper across its range both ways from rest and record the error to the target.
    The caller restores the state afterwards."""
    curves = []
    for start, target in ((open_value, closed_value), (closed_value, open_value)):
        drive(start)
        for _ in range(int(0.5 / dt)):  # settle at the start value
            p.stepSimulation(physicsClientId=client)
        drive(target)
        errors = []
        for _ in range(int(limit_s / dt)):
            p.stepSimulation(physicsClientId=client)
            value, speed = p.getJointState(body, joint, physicsClientId=client)[:2]
            errors.append(abs(target - value))
            if abs(speed) < JOINT_REST and abs(target - value) < 1e-4:
                break
        full = abs(target - start)
        curve = np.minimum.accumulate(np.array([full, *errors]))  # the curve is read as monotone
        curves.append(curve)
    closing_sign = np.sign(closed_value - open_value)
    closing, opening = curves if closing_sign > 0 else curves[::-1]
    return GripperResponse(closing, opening, dt)


@dataclass(frozen=True)
class Rig:
    """What a cycle needs of the backend: the robot body, its arm joints in action order, their rated speeds, the
    gripper joint, and the backend's joint setter
    (q_arm, gripper, gripper_speed), which moves the gripper's mimic followers along."""

    client: int
    body: int
    arm: list[int]
    arm_speed_limits: np.ndarray  # the joints' rated speeds, which set how long a commanded motion lasts
    arm_limits: np.ndarray  # (2, joints): the lower and upper limits PyBullet holds the arm joints in
    gripper: int | None
    dt: float
    set_joints: Callable[[np.ndarray, float | None, float], None]
    program_motors: Callable[[], None]  # gives the arm's motors the last command: called before any substep
    substep: Callable[[], None]  # one physics substep, the arm's motors on the commanded profile


class FastCycles:
    """Plays action cycles kinematically, not at all, or dynamically (see the module docstring)."""

    def __init__(self, rig: Rig, clearance: ObjectClearance, gripper: GripperResponse | None):
        self.rig, self.clearance, self.gripper_response = rig, clearance, gripper
        self.counts = CycleCounts()
        self.arm_target, self.arm_duration, self.gripper_target = None, 0.0, None
        self.arm_motion_s = 0.0  # how long the motors' profile to arm_target lasts, once a cycle has read the arm
        self._motion_known = True
        self.objects_at_rest = False

    def reset(self, arm_target, gripper_target: float | None, has_objects: bool) -> None:
        self.arm_target = np.asarray(arm_target, float)
        self.arm_duration = self.arm_motion_s = 0.0
        self._motion_known = True
        self.gripper_target = gripper_target
        # a freshly spawned object has not been seen resting yet
        self.objects_at_rest = not has_objects

    def commanded_arm(self, target, duration: float) -> None:
        self.arm_target, self.arm_duration = np.asarray(target, float), duration
        self._motion_known = False  # the next cycle reads where the arm starts from anyway

    def commanded_gripper(self, value: float) -> None:
        self.gripper_target = float(value)

    # ---------------------------------------------------------------- one cycle

    def play(self, seconds: float, objects: dict[tuple[int, int], float]) -> int:
        """Let one cycle pass; `objects` maps each movable (body, link) to the radius of the sphere about its frame
        that holds what the fingers could touch of it (link -1: a free object's base; else a fixture's moving link).
        Returns the substeps run."""
        substeps = max(1, round(seconds / self.rig.dt))
        q, q_speed = self._arm_state()
        if not self._motion_known:
            # the length the backend's profile will take, from the same start (program_pending_arm)
            self.arm_motion_s = synchronous_length(q, self.arm_target, self.arm_duration, self.rig.arm_speed_limits)
            self._motion_known = True
        gripper, gripper_speed = self._gripper_state()
        if np.abs(q_speed).max() >= JOINT_REST:  # the arm still moves from the last cycle
            return self._play_dynamic(substeps, objects)
        if self.objects_at_rest:
            gripper_still = gripper is None or (
                abs(self.gripper_target - gripper) < SETTLED and abs(gripper_speed) < JOINT_REST
            )
            if gripper_still and np.abs(self.arm_target - q).max() < SETTLED:
                self.counts.at_rest += 1
                return 0
        plan = self._kinematic_plan(q, gripper, substeps, objects) if self._settles(substeps) else None
        if plan is None:
            return self._play_dynamic(substeps, objects)
        done = 0
        if not self.objects_at_rest:
            self.rig.program_motors()
        while not self.objects_at_rest:
            # objects not yet seen resting (fresh from a reset: sinking into their contact, or dropped the few mm
            # a spec spawns them above the table, ~50 substeps at 240 Hz): simulated until they rest, with the
            # arm on its way along the path proven clear; one still moving at the cycle's end had it all
            if done >= substeps:
                return self._play_dynamic(substeps, objects, done)
            for _ in range(REST_CHECK_EVERY):
                self.rig.substep()
            done += REST_CHECK_EVERY
            self.objects_at_rest = self._objects_at_rest(objects)
        if done:
            # they came to rest where the proof did not look: it is renewed there before the arm is placed
            plan = self._kinematic_plan(q, gripper, substeps, objects)
            if plan is None:
                return self._play_dynamic(substeps, objects, done)
        self._apply(*plan)
        self.counts.kinematic += 1
        self.counts.substeps += done
        return done

    def _settles(self, substeps: int) -> bool:
        """Whether the motors land the arm on its target well within the cycle, as the kinematic arm is."""
        return substeps - np.ceil(self.arm_motion_s / self.rig.dt) >= SETTLE_SUBSTEPS

    def _kinematic_plan(self, q, gripper, substeps: int, objects):
        """Where the cycle ends (arm, gripper, gripper speed) if it may be played kinematically, else None."""
        rig, arm_target = self.rig, self.arm_target
        low, high = rig.arm_limits
        if (np.minimum(np.minimum(q, arm_target) - low, high - np.maximum(q, arm_target)) < NEAR_LIMIT).any():
            return None  # a joint limit's constraint holds the joint a little off where the motor sends it
        gripper_end = gripper_speed = None
        if gripper is not None:
            response = self.gripper_response.advance(gripper, self.gripper_target, substeps)
            if response is None:
                return None
            gripper_end, gripper_speed = response
        if objects:
            parts = list(objects)
            centers = np.array([self._frame_position(part) for part in parts])
            radii = np.array([objects[part] for part in parts])
            if not self.clearance.motion_is_clear(
                q,
                0.0 if gripper is None else gripper,
                arm_target,
                0.0 if gripper is None else gripper_end,
                centers,
                radii,
                NEAR_CONTACT,
            ):
                return None
        return arm_target, gripper_end, gripper_speed

    def _apply(self, arm_target, gripper_end, gripper_speed) -> None:
        self.rig.set_joints(arm_target, gripper_end, 0.0 if gripper_speed is None else gripper_speed)

    def _play_dynamic(self, substeps: int, objects, done: int = 0) -> int:
        rig = self.rig
        rig.program_motors()
        self.counts.dynamic += 1
        step = rig.substep
        # the commanded motion is over after action_speed; the gripper may run on, the rest test sees it
        motion = min(substeps, int(np.ceil(self.arm_motion_s / rig.dt)) + 1)
        for _ in range(done, motion):
            step()
        done = max(done, motion)
        resting = False
        while done < substeps:
            chunk = min(REST_CHECK_EVERY, substeps - done)
            for _ in range(chunk):
                step()
            done += chunk
            # at rest at two checks in a row: one slow check can catch a bounce at its turning point
            was_resting, resting = resting, self._objects_at_rest(objects) and self._robot_at_rest()
            if resting and was_resting:
                break  # what is left of the cycle would hold still
        self.objects_at_rest = self._objects_at_rest(objects)
        self.counts.substeps += done
        return done

    # ---------------------------------------------------------------- readings

    def _arm_state(self) -> tuple[np.ndarray, np.ndarray]:
        states = p.getJointStates(self.rig.body, self.rig.arm, physicsClientId=self.rig.client)
        return np.array([s[0] for s in states]), np.array([s[1] for s in states])

    def _gripper_state(self) -> tuple[float | None, float]:
        if self.rig.gripper is None:
            return None, 0.0
        value, speed = p.getJointState(self.rig.body, self.rig.gripper, physicsClientId=self.rig.client)[:2]
        return value, speed

    def _robot_at_rest(self) -> bool:
        rig = self.rig
        joints = rig.arm + ([rig.gripper] if rig.gripper is not None else [])
        speeds = [abs(s[1]) for s in p.getJointStates(rig.body, joints, physicsClientId=rig.client)]
        if rig.gripper is not None and speeds.pop() >= GRIPPER_REST:
            return False
        return max(speeds) < JOINT_REST

    def _frame_position(self, part: tuple[int, int]):
        body, link = part
        if link < 0:
            return p.getBasePositionAndOrientation(body, physicsClientId=self.rig.client)[0]
        return p.getLinkState(body, link, computeForwardKinematics=1, physicsClientId=self.rig.client)[4]

    def _objects_at_rest(self, objects) -> bool:
        client = self.rig.client
        for body, link in objects:
            if link < 0:
                linear, angular = p.getBaseVelocity(body, physicsClientId=client)
            else:
                linear, angular = p.getLinkState(
                    body, link, computeLinkVelocity=1, computeForwardKinematics=1, physicsClientId=client
                )[6:8]
            if np.linalg.norm(linear) >= OBJECT_REST or np.linalg.norm(angular) >= OBJECT_SPIN_REST:
                return False
        return True
