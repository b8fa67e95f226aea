"""How MuJoCo plays one action cycle: the arm's and the gripper's profiles, the servos that track them substep by
substep, and, under `sim.fidelity: fast`, the cycles that need no dynamics. Its public face is PyBullet's
fast_cycles.FastCycles's: reset, commanded_arm, commanded_gripper, play.

A cycle is played one of four ways (the reference, `full`, always takes the last):
- at rest: arm, gripper and objects are still and every command is reached: nothing to simulate;
- kinematic: every object rests and the whole commanded motion of the arm's moving shapes and the gripper is
  proven NEAR_CONTACT away from each object's bounding sphere (the proof PyBullet's fast fidelity uses,
  envfactory/geometry/object_clearance.py): the arm is set on its target and the gripper where its drive
  takes it, without a substep;
- carried: an object held in a stable grasp rides with the hand while the motion is proven clear of every
  other shape (held.py);
- dynamic: the substeps of the commanded motion, then more in small chunks until arm, gripper and objects
  are at rest twice in a row; the rest of the cycle would hold still, so it is not simulated.

An arm command is played as the real controllers play it (UR's trajectory controller, xs_sdk): every arm
joint moves together along the straight joint-space line from where the arm is to the target, arriving at
the same time, over `duration` or longer when a joint's velocity limit needs it.
"""

from __future__ import annotations

import mujoco
import numpy as np
from mujoco import rollout

from envfactory.backends.at_rest import GRIPPER_REST, JOINT_REST, OBJECT_REST, OBJECT_SPIN_REST, CycleCounts
from envfactory.backends.mujoco.held import Carry
from envfactory.backends.mujoco.model import ROBOT_PREFIX
from envfactory.backends.synchronous import Profile, synchronous_length
from envfactory.geometry.object_clearance import NEAR_CONTACT, ObjectClearance
from envfactory.geometry.obstacles import scene_obstacles
from envfactory.schema.models import ComposedSpec

STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS
CONTROL = int(mujoco.mjtState.mjSTATE_CTRL | mujoco.mjtState.mjSTATE_QFRC_APPLIED)  # what each substep's row sets
# A joint within this of its commanded target (rad, or m for a finger) has reached it
REST_GAP = 1e-6

# The servos follow the profile's quintic with a lag of a few substeps; a cycle played kinematically must
# leave them this long after the profile ends, as the dynamic cycle would (the tracking test in
# tests/test_mujoco.py measures what remains).
SETTLE_TIME = 0.1
# Once the commanded motion is over, the rest test runs every this many substeps.
REST_CHECK_EVERY = 8


def objects_at_rest(data, object_dofs: dict[str, int], fixture_dofs=()) -> bool:
    """Every object's free joint slower than the rest limits (linear, then angular: its six dofs), and every
    fixture's slide slower than the linear one; squared speeds against squared limits on plain floats: a test
    every cycle makes."""
    for dof in object_dofs.values():
        vx, vy, vz, wx, wy, wz = data.qvel[dof : dof + 6].tolist()
        # asked as "below the limits", so that a NaN (a blown-up state) is never taken for rest
        if not (vx * vx + vy * vy + vz * vz < OBJECT_REST**2 and wx * wx + wy * wy + wz * wz < OBJECT_SPIN_REST**2):
            return False
    for dof in fixture_dofs:
        speed = float(data.qvel[dof])
        if not speed * speed < OBJECT_REST**2:
            return False
    return True


def robot_at_rest(data, arm_dof, gripper_dof: int | None) -> bool:
    """`arm_dof`: the arm's dof addresses (a slice or an index array)."""
    if gripper_dof is not None and not abs(data.qvel[gripper_dof]) < GRIPPER_REST:
        return False
    return all(abs(speed) < JOINT_REST for speed in data.qvel[arm_dof].tolist())  # a few numbers: plain floats


def _as_slice(indices: np.ndarray):
    """Addresses that run in order (a serial arm's qpos, dofs and actuators) as a slice: a kinematic cycle reads
    and writes them a dozen times, and a slice does it several times faster than an index array."""
    indices = np.asarray(indices, dtype=int)
    if indices.size and np.array_equal(indices, np.arange(indices[0], indices[0] + indices.size)):
        return slice(int(indices[0]), int(indices[0]) + indices.size)
    return indices


class FastCycles:
    """The cycles of one env's MuJoCo data: the commanded profiles, the clock, and how each cycle is played
    (at rest, kinematic, carried or dynamic; only dynamic under `full`). `counts` says how they were played."""

    def __init__(self, spec: ComposedSpec, model, data, handles, fixtures: dict | None = None):
        self.model, self.data, self.handles = model, data, handles
        self.robot = spec.robot
        self.dt = model.opt.timestep
        self.fast = spec.sim.fidelity == "fast"
        self._velocities = np.asarray(self.robot.arm_velocities, float)
        # kv / kp of each servo (the position actuator keeps kp in gainprm[0] and -kv in biasprm[2])
        gains = model.actuator_gainprm[:, 0]
        damping = -model.actuator_biasprm[:, 2]
        self._lead = damping[handles.arm_actuators] / gains[handles.arm_actuators]
        self._scratch = mujoco.MjData(model)
        self._rollout = rollout.Rollout(nthread=0)  # in the calling thread: one env, one core
        self._mass = np.zeros((model.nv, model.nv))
        self._state = np.zeros(mujoco.mj_stateSize(model, STATE))
        self._controls = np.zeros((0, model.nu + model.nv))
        self._states = np.zeros((1, 0, self._state.size))
        self._arm: Profile | None = None
        self._gripper: Profile | None = None
        self.sim_time = 0.0
        self._clearance: ObjectClearance | None = None  # once attach gives the safety check's shapes
        fixtures = fixtures or {}
        # what the fingers could touch: each object's bounding sphere, and each fixture's touchable part's
        self._object_radii = np.array(
            [obj.bounding_radius for obj in spec.task.objects.values()]
            + [fixture.touch_radius for fixture in fixtures.values()]
        )
        self._object_bodies = [handles.object_body[name] for name in spec.task.objects] + [
            handles.fixture_body[name] for name in fixtures
        ]
        self._fixture_dofs = tuple(dof for _, dof, _ in handles.fixture_joint.values())
        self.counts = CycleCounts()
        self._settled = False
        self._arm_q, self._arm_v = _as_slice(handles.arm_qpos), _as_slice(handles.arm_dof)
        self._arm_u = _as_slice(handles.arm_actuators)
        # the gripper joint and its mimic followers: (qpos address, dof address, gain) of each
        moved = (
            []
            if handles.gripper_qpos is None
            else [(handles.gripper_qpos, handles.gripper_dof, 1.0), *handles.followers]
        )
        self._gripper_qpos = np.array([address for address, _, _ in moved], dtype=int)
        self._gripper_dofs = np.array([dof for _, dof, _ in moved], dtype=int)
        self._gripper_gains = np.array([gain for _, _, gain in moved], dtype=float)
        self._carry: Carry | None = None
        if self.fast and spec.sim.mujoco.carry_held and spec.robot.gripper is not None and spec.task.objects:
            pads = {model.body(ROBOT_PREFIX + link).id for link in spec.robot.gripper.pads.links}
            radii = dict(zip(spec.task.objects, self._object_radii[: len(spec.task.objects)]))
            self._carry = Carry(model, handles, pads, scene_obstacles(spec), radii)

    def attach(self, collision) -> None:
        """The safety check's collision model: with the fast fidelity it proves motions clear of the objects."""
        if self.fast:
            self._clearance = ObjectClearance(collision)

    def reset(self, q_arm: np.ndarray) -> None:
        """After the backend placed the scene: no profile, the clock at 0, the scene not yet seen settled."""
        self.data.qpos[self._arm_q] = q_arm
        self.data.ctrl[self._arm_u] = q_arm
        self._arm = self._gripper = None
        self.sim_time = 0.0
        self._settled = False
        if self._carry is not None:
            self._carry.reset()

    def place_gripper(self, value: float, speed: float = 0.0) -> None:
        """The gripper joint and its mimic followers (one indexed write each: every kinematic cycle places them)."""
        gains = self._gripper_gains
        self.data.qpos[self._gripper_qpos] = gains * value
        self.data.qvel[self._gripper_dofs] = gains * speed

    def commanded_arm(self, target, duration: float) -> None:
        start = self.data.qpos[self._arm_q].copy()
        end = np.asarray(target, float)
        self._arm = Profile(start, end, self.sim_time, synchronous_length(start, end, duration, self._velocities))

    def commanded_gripper(self, value: float) -> None:
        if self._gripper is not None and self._gripper.end == value:
            return  # already on its way there: a repeated command does not restart the drive
        # one joint: its profile on plain floats (a kinematic cycle asks it where the gripper ends)
        start, end = float(self.data.qpos[self.handles.gripper_qpos]), float(value)
        self._gripper = Profile(
            start, end, self.sim_time, abs(end - start) / self.robot.gripper.max_velocity, smooth=False
        )

    def hold(self) -> None:
        """Hold the arm where it is now."""
        here = self.data.qpos[self._arm_q].copy()
        self._arm = Profile(here, here, self.sim_time, 0.0)

    def play(self, seconds: float) -> None:
        """Let one cycle of `seconds` pass: in full, or (fast) without the substeps that cannot change what the
        cycle ends with."""
        self._simulate(seconds)

    def close(self) -> None:
        self._rollout.close()

    def _simulate(self, seconds: float) -> None:
        """Let one cycle of `seconds` pass: in full, or (sim.fidelity fast) without the substeps that cannot
        change what the cycle ends with (py)."""
        steps = max(1, round(seconds / self.dt))
        end = self.sim_time + steps * self.dt
        q_start = self.data.qpos[self._arm_q].copy()
        if self.fast and self._at_rest():
            self.counts.at_rest += 1
        elif self.fast and self._carried(end):
            self.counts.carried += 1
        else:
            placed, done = False, 0
            if self.fast and self._kinematic(end):
                placed = True
            elif self.fast and not self._settled:
                placed, done = self._settle_then_place(steps, end)
            if placed:
                self.counts.kinematic += 1
                self.counts.substeps += done
            else:
                self.counts.dynamic += 1
                self.counts.substeps += self._dynamic(steps, done)
            self._settled = True  # every path here either found the scene settled or simulated until it was
            if self._carry is not None:
                arm = self._arm
                self._carry.measure(
                    self.data, q_start, q_start if arm is None else arm.end, 0.0 if arm is None else arm.length
                )
        self.data.time = self.sim_time = end

    def _dynamic(self, steps: int, done: int = 0) -> int:
        """The substeps of the commanded motion (after the `done` first ones, already played), then (fast) chunks
        until everything rests twice in a row."""
        motion_end = max(
            (
                profile.t0 + profile.length
                for profile in (self._arm, self._gripper)
                if profile is not None and np.max(np.abs(profile.end - profile.start)) > REST_GAP
            ),
            default=0.0,
        )  # a hold has nothing to play out: the rest test decides at once
        motion = steps if not self.fast else min(steps, max(1, int(np.ceil((motion_end - self.sim_time) / self.dt))))
        if motion > done:
            self._play_substeps(done, motion - done)
            done = motion
        done, _ = self._play_until_rest(done, steps, self._scene_at_rest)  # what is left would hold still
        # the rest test reads only velocities, which the state holds: positions, contacts and frames are
        # computed once, for the cycle's end
        mujoco.mj_forward(self.model, self.data)
        return done

    def _play_until_rest(self, done: int, steps: int, at_rest) -> tuple[int, bool]:
        """Substeps after the `done` first ones, in chunks, until `at_rest()` holds at two checks in a row (one
        check can catch a bounce at its turning point) or the cycle's `steps` are played: the substeps played by
        then, and whether it came to rest."""
        resting = was_resting = False
        while done < steps and not (resting and was_resting):
            chunk = min(REST_CHECK_EVERY, steps - done)
            self._play_substeps(done, chunk)
            done += chunk
            was_resting, resting = resting, at_rest()
        return done, resting and was_resting

    def _play_substeps(self, first: int, steps: int) -> None:
        """Simulate substeps first+1 … first+steps of the cycle: the controls of every substep are laid out
        first (the servo targets along the profiles, led by kv/kp times the profile's velocity so that the
        servo is kp (q_ref - q) + kv (qdot_ref - qdot); the profile's acceleration times the arm's inertia fed
        forward, as a trajectory controller does), then MuJoCo plays them all in one call."""
        model, data, handles = self.model, self.data, self.handles
        start = self.sim_time + self.dt * (first + 1)
        if all(profile is None or start >= profile.t0 + profile.length for profile in (self._arm, self._gripper)):
            self._hold_substeps(steps)
            return
        times = self.sim_time + self.dt * np.arange(first + 1, first + steps + 1)
        controls = self._controls
        if controls.shape[0] < steps:
            controls = self._controls = np.zeros((steps, model.nu + model.nv))
        controls = controls[:steps]
        controls[:, : model.nu] = data.ctrl
        controls[:, model.nu :] = 0.0
        if self._arm is not None:
            position, velocity, acceleration = self._arm.at(times)
            controls[:, handles.arm_actuators] = position + self._lead * velocity
            if times[0] < self._arm.t0 + self._arm.length:  # once the profile has ended nothing is fed forward
                mujoco.mj_fullM(model, data, self._mass)
                dofs = handles.arm_dof
                controls[:, model.nu + dofs] = acceleration @ self._mass[np.ix_(dofs, dofs)].T
        if self._gripper is not None:
            controls[:, handles.gripper_actuator] = self._gripper.at(times)[0][:, 0]  # (times, 1): its one joint
        mujoco.mj_getState(model, data, self._state, STATE)
        # the solver's warm start is no part of the state: carried across, so that the rollout and the substeps
        # stepped in place continue one another as one run of substeps would
        self._scratch.qacc_warmstart[:] = data.qacc_warmstart
        if self._states.shape[1] != steps:
            self._states = np.zeros((1, steps, self._state.size))
        self._rollout.rollout(
            [model],
            [self._scratch],
            self._state[None],
            np.ascontiguousarray(controls[None]),
            control_spec=CONTROL,
            skip_checks=True,
            nstep=steps,
            state=self._states,
        )
        mujoco.mj_setState(model, data, self._states[0, -1], STATE)
        data.qacc_warmstart[:] = self._scratch.qacc_warmstart
        data.ctrl[:] = controls[-1, : model.nu]

    def _hold_substeps(self, steps: int) -> None:
        """Substeps after every profile has ended: the servos hold the profiles' ends and nothing is fed forward,
        so each substep's controls are the same and MuJoCo steps in place (the rest test's small chunks would
        cost more in laying out and copying a rollout's controls and states than in the substeps themselves)."""
        model, data, handles = self.model, self.data, self.handles
        if self._arm is not None:
            data.ctrl[self._arm_u] = self._arm.end  # the profile's velocity is zero: no lead
        if self._gripper is not None:
            data.ctrl[handles.gripper_actuator] = self._gripper.end
        # (the feed-forward forces go into the rollout's own controls: this data's qfrc_applied stays zero)
        step = mujoco.mj_step
        for _ in range(steps):
            step(model, data)

    def _at_rest(self) -> bool:
        """Whether a cycle would change nothing: every body at rest and every command already reached."""
        if not self._settled:
            return False  # a scene just placed is not at rest before its contacts have carried its weight
        # the commands first: most cycles have the arm on its way, which settles it without reading velocities
        # (asked as "within", so that a NaN is never taken for a reached target)
        here = self.data.qpos
        if self._arm is not None and not all(
            abs(gap) <= REST_GAP for gap in (self._arm.end - here[self._arm_q]).tolist()
        ):
            return False
        gripper = self._gripper
        if (
            gripper is not None
            and self.sim_time < gripper.t0 + gripper.length
            and abs(gripper.end - gripper.start) > REST_GAP
        ):
            return False  # still on its way (one stopped short of its target squeezes something: that is rest)
        return self._scene_at_rest()

    def _scene_at_rest(self) -> bool:
        handles = self.handles
        return objects_at_rest(self.data, handles.object_dof, self._fixture_dofs) and robot_at_rest(
            self.data, self._arm_v, handles.gripper_dof
        )

    def _arm_lands_unsimulated(self, end: float) -> bool:
        """What every unsimulated motion needs: a scene seen settled, and the arm able to land by `end`."""
        return self._settled and self._arm_can_land(end)

    def _arm_can_land(self, end: float) -> bool:
        """The arm still now, and its profile over SETTLE_TIME before `end` (else the servos would still be on
        their way at the reading)."""
        arm = self._arm
        return robot_at_rest(self.data, self._arm_v, None) and (arm is None or arm.t0 + arm.length <= end - SETTLE_TIME)

    def _land_arm(self, q_arm: np.ndarray) -> None:
        data = self.data
        data.qpos[self._arm_q] = q_arm
        data.qvel[self._arm_v] = 0.0
        data.ctrl[self._arm_u] = q_arm

    def _carried(self, end: float) -> bool:
        """Carry a held object with the hand, without dynamics, if the carry is proven clear (held.py)."""
        data, handles, arm, gripper = self.data, self.handles, self._arm, self._gripper
        if self._carry is None or arm is None or gripper is None or self.sim_time < gripper.t0 + gripper.length:
            return False  # nothing can be held while the gripper is still on its way
        if not self._arm_lands_unsimulated(end):
            return False
        name = self._carry.held(data)
        plan = (
            None if name is None else self._carry.plan(data, name, data.qpos[self._arm_q].copy(), arm.end, arm.length)
        )
        if plan is None:
            return False
        position, rotation = plan
        self._land_arm(arm.end)
        address, dof = handles.object_qpos[name], handles.object_dof[name]
        quaternion = np.zeros(4)
        mujoco.mju_mat2Quat(quaternion, rotation.reshape(-1))
        data.qpos[address : address + 7] = [*position, *quaternion]
        data.qvel[dof : dof + 6] = 0.0
        mujoco.mj_forward(self.model, data)
        return True

    def _kinematic(self, end: float) -> bool:
        """Play the cycle without dynamics if the motion is proven clear of every object (py)."""
        data, handles = self.data, self.handles
        if (
            self._clearance is None
            or not objects_at_rest(data, handles.object_dof, self._fixture_dofs)
            or not self._arm_lands_unsimulated(end)
        ):
            return False
        landing = self._landing(data.qpos[self._arm_q].copy(), self._gripper_value(), end)
        if landing is None:
            return False
        self._land(*landing)
        return True

    def _settle_then_place(self, steps: int, end: float) -> tuple[bool, int]:
        """A scene fresh from a reset is not at rest before its contacts have carried its objects' weight (sinking
        into them, or dropped the few millimetres a spec spawns them above the table): the cycle is simulated, the
        arm on its way along a path proven clear of the objects, only until they rest; then the proof is renewed
        where they came to rest and the arm is placed as a kinematic cycle places it. Whether it was placed, and
        the substeps simulated (the cycle's dynamics go on from there when it was not)."""
        data, handles = self.data, self.handles
        if self._clearance is None or not self._object_bodies or not self._arm_can_land(end):
            return False, 0
        q_from, g_from = data.qpos[self._arm_q].copy(), self._gripper_value()
        if self._landing(q_from, g_from, end) is None:
            return False, 0
        done, rested = self._play_until_rest(
            0, steps, lambda: objects_at_rest(data, handles.object_dof, self._fixture_dofs)
        )
        landing = self._landing(q_from, g_from, end) if rested and done < steps else None
        if landing is None:
            return False, done
        self._land(*landing)
        return True, done

    def _gripper_value(self) -> float:
        return 0.0 if self._gripper is None else float(self.data.qpos[self.handles.gripper_qpos])

    def _landing(self, q_from: np.ndarray, g_from: float, end: float):
        """Where the cycle's motion from (q_from, g_from) ends (arm, gripper value and speed) if it is proven clear
        of every object where they are now; else None."""
        arm, gripper = self._arm, self._gripper
        q_to = q_from if arm is None else arm.end
        g_to = g_speed = 0.0
        if gripper is not None:
            # a gripper on its way is no obstacle: its drive's profile says where it will be
            g_to, g_speed, _ = gripper.at(end)
        if self._object_bodies and not self._clearance.motion_is_clear(
            q_from, g_from, q_to, g_to, self.data.xpos[self._object_bodies], self._object_radii, NEAR_CONTACT
        ):
            return None
        return q_to, g_to, g_speed

    def _land(self, q_to: np.ndarray, g_to: float, g_speed: float) -> None:
        data = self.data
        self._land_arm(q_to)
        if self._gripper is not None:
            self.place_gripper(g_to, g_speed)
            data.ctrl[self.handles.gripper_actuator] = g_to
        # frames, cameras and lights for the readers; not collisions and forces (most of mj_forward): a motion proven
        # clear of the objects starts no contact a reader asks about, and the next simulated substep computes them
        mujoco.mj_kinematics(self.model, data)
        mujoco.mj_comPos(self.model, data)
        mujoco.mj_camlight(self.model, data)
