"""The embedded PyBullet backend: headless DIRECT by default, GUI on request."""

from __future__ import annotations

import json
import math
import threading
import time
from pathlib import Path

import numpy as np
import pinocchio as pin
import pybullet as p

from envfactory.backends.base import (
    PHYSICS_QUANTITIES,
    BackendError,
    CameraFrame,
    JointReading,
    ObjectReading,
    PhysicsChange,
    window_impossible,
)
from envfactory.backends.driver_readings import DriverReadings
from envfactory.backends.pybullet import scene
from envfactory.backends.pybullet.fast_cycles import FastCycles, GripperResponse, Rig, record_gripper_response
from envfactory.backends.pybullet.recorded_responses import load_or_record
from envfactory.backends.synchronous import Profile, synchronous_length
from envfactory.backends.view import RENDER_SIZE
from envfactory.geometry.frames import TaskFrame, base_rotation
from envfactory.geometry.object_clearance import ObjectClearance
from envfactory.geometry.obstacles import TABLE_TOP, scene_obstacles
from envfactory.geometry.urdf_assembly import without_visuals
from envfactory.schema.models import CameraSpec, ComposedSpec

# The gripper's recorded step response, per robot and physics settings: recorded once per process.
_GRIPPER_RESPONSES: dict[tuple, GripperResponse] = {}


class PyBulletBackend:
    """The Backend protocol on PyBullet: one client per env (DIRECT, or GUI on request), the robot from its
    assembled URDF with gear-constrained mimic joints, the scene and the task's objects. Arm motors move all
    joints together along the commanded line; with the fast fidelity (fast_cycles.FastCycles) cycles that
    cannot change an object are played without substeps. In realtime mode a thread steps physics at wall-clock
    rate, guarded by a lock."""

    teleports_on_reset = True  # reset sets the joints directly; no path is driven

    def __init__(
        self,
        spec: ComposedSpec,
        urdf_path: Path,
        task_frame: TaskFrame,
        render_mode: str | None = None,
        headless: bool = False,
        fixtures: dict | None = None,
    ):
        self.spec = spec
        self.fixtures = fixtures or {}  # name -> geometry.fixtures.FixtureModel
        self.robot = spec.robot
        self._urdf_path = Path(urdf_path)
        self.task_frame = task_frame
        self.dt = 1.0 / spec.sim.physics_hz
        self._position_gain = spec.sim.motor_position_gain
        self.realtime = spec.env.timing.realtime
        mode = p.GUI if (spec.env.gui or render_mode == "human") and not headless else p.DIRECT
        # a session that shows nothing loads no visual meshes; rgb_array frames, the GUI and camera terms need them
        self._draws = render_mode is not None or mode == p.GUI or spec.env.observation.camera_images
        if mode == p.GUI and window_impossible():
            asked = "render_mode='human'" if render_mode == "human" else "gui=True (env.gui)"
            raise BackendError(
                f"{asked} opens PyBullet's window, and this machine has no display (DISPLAY is "
                "unset); use render_mode='rgb_array' for frames, or run where there is a display (a "
                "desktop session, ssh -X, or xvfb-run)"
            )
        try:
            self.client = p.connect(mode)
        except p.error as exc:
            raise BackendError(f"PyBullet could not open a {'GUI' if mode == p.GUI else 'DIRECT'} session: {exc}")
        if self.client < 0:
            raise BackendError("PyBullet could not connect (is a display available for the GUI?)")
        self._lock = threading.Lock()
        self._closed = False
        self._sim_time = 0.0
        try:
            self._build(urdf_path)
        except Exception:
            p.disconnect(self.client)
            raise
        self._fast: FastCycles | None = None  # sim.fidelity fast, once attach_geometry gives the shapes
        self._pending_arm: tuple[np.ndarray, float] | None = None  # a command the arm's motors do not have yet
        # the motors' (targets, speeds) for each substep of the motion under way, and the next row to play
        self._arm_rows: tuple[list, list] | None = None
        self._arm_row = 0
        self._object_radii: dict[tuple[int, int], float] = {}
        self._thread = None
        if self.realtime:
            self._thread = threading.Thread(target=self._run_realtime, name="pybullet-realtime", daemon=True)
            self._thread.start()

    # ---------------------------------------------------------------- scene

    def _build(self, urdf_path: Path) -> None:
        c = self.client
        p.resetSimulation(physicsClientId=c)
        p.setGravity(0, 0, -9.81, physicsClientId=c)
        p.setTimeStep(self.dt, physicsClientId=c)
        # Contact pairs in a fixed order: without it a cycle replayed from a saved state (the fidelity probe)
        # can end centimetres apart once a cube tumbles, as the order of the last run carries over.
        p.setPhysicsEngineParameter(
            numSolverIterations=self.spec.sim.solver_iterations, deterministicOverlappingPairs=1, physicsClientId=c
        )
        p.configureDebugVisualizer(p.COV_ENABLE_GUI, 0, physicsClientId=c)
        obstacles = scene_obstacles(self.spec)
        self.obstacle_bodies = scene.add_obstacles(c, obstacles)
        self._table_body = self.obstacle_bodies[[o.name for o in obstacles].index(TABLE_TOP)]
        mount = np.asarray(self.robot.mount, float)
        x, y, z, w = pin.Quaternion(base_rotation(self.robot)).coeffs()
        # Self-collision stays off: the gripper's linkage links overlap by design.
        self.body = p.loadURDF(
            str(urdf_path if self._draws else without_visuals(urdf_path)),
            basePosition=mount.tolist(),
            baseOrientation=[x, y, z, w],
            useFixedBase=True,
            flags=p.URDF_USE_INERTIA_FROM_FILE,
            physicsClientId=c,
        )
        infos = [
            p.getJointInfo(self.body, j, physicsClientId=c) for j in range(p.getNumJoints(self.body, physicsClientId=c))
        ]
        index = {info[1].decode(): info[0] for info in infos}
        link_index = {info[12].decode(): info[0] for info in infos}
        self._arm = [index[j.name] for j in self.robot.arm_joints]
        self._efforts, self._velocities = self.robot.arm_efforts, self.robot.arm_velocities
        self._speed_limits = np.asarray(self._velocities, float)
        self._position_gains = [self._position_gain] * len(self._arm)
        self._velocity_gains = [1.0] * len(self._arm)  # the profile's speed is fed forward in full
        self._driver_readings = DriverReadings(self.robot)
        self._state_joints = [index[e.urdf_joint] for e in self.robot.joint_states]
        # Unactuated joints would otherwise hold still under PyBullet's default velocity motors.
        for joint in index.values():
            p.setJointMotorControl2(self.body, joint, p.VELOCITY_CONTROL, force=0.0, physicsClientId=c)
        self._gripper = None
        if self.robot.gripper is not None:
            gripper = self.robot.gripper
            self._gripper_force, self._gripper_target = gripper.force, gripper.open
            self._gripper = index[gripper.joint]
            self._gripper_followers = scene.link_gripper(c, self.body, self.robot, index, link_index)
        self.objects: dict[str, int] = {}  # spawned fresh at every reset
        # fixtures stand for the session: the saved state below holds their joints closed for every reset
        self._fixture_parts = {name: scene.add_fixture(c, fixture) for name, fixture in self.fixtures.items()}
        self._goal_marker = scene.add_marker(c, self.task_frame.to_world([0.0, 0.0, -10.0]))
        self._set_joint_state(np.asarray(self.robot.home, float), self._gripper_reset_value(None))
        self._hold(np.asarray(self.robot.home, float), None)
        self._saved = p.saveState(physicsClientId=c)

    def attach_geometry(self, collision) -> None:
        """The safety check's collision model: with `sim.fidelity: fast` it proves motions clear of the
        movable objects, so those cycles are played without dynamics (fast_cycles.py)."""
        if self.spec.sim.fidelity != "fast" or self.realtime:
            return
        limits = np.array(
            [p.getJointInfo(self.body, joint, physicsClientId=self.client)[8:10] for joint in self._arm]
        ).T
        unlimited = limits[0] >= limits[1]  # how PyBullet reports a continuous joint
        limits[:, unlimited] = [[-np.inf], [np.inf]]
        rig = Rig(
            self.client,
            self.body,
            self._arm,
            self._speed_limits,
            limits,
            self._gripper,
            self.dt,
            self._set_joint_state,
            self.program_pending_arm,
            self._substep,
        )
        response = None
        if self._gripper is not None:
            gripper = self.robot.gripper
            settings = {
                "dt": self.dt,
                "solver_iterations": self.spec.sim.solver_iterations,
                "gripper": [gripper.open, gripper.closed, gripper.force, gripper.max_velocity],
                # the recording session's scene and pose, in case an obstacle stood in the fingers' way
                "scene": self.spec.scene.model_dump_json(),
                "pose": [list(self.robot.mount), list(self.robot.mount_rpy), list(self.robot.home)],
            }
            key = (self.robot.name, str(self._urdf_path), json.dumps(settings))
            if key not in _GRIPPER_RESPONSES:
                _GRIPPER_RESPONSES[key] = load_or_record(
                    without_visuals(self._urdf_path), settings, self._record_gripper_response
                )
            response = _GRIPPER_RESPONSES[key]
        self._fast = FastCycles(rig, ObjectClearance(collision), response)
        self._fast.reset(np.asarray(self.robot.home, float), self._gripper_reset_value(None), has_objects=False)

    def _record_gripper_response(self) -> GripperResponse:
        """The gripper's step response, recorded in a session of its own: seconds of recording in this one
        would leave its solver warm where a later env's is cold, and two envs made from one seed would
        then not play the same episode."""
        recorder = PyBulletBackend(self.spec, self._urdf_path, self.task_frame, headless=True)
        try:
            gripper = self.robot.gripper
            return record_gripper_response(
                recorder.client,
                recorder.body,
                recorder._gripper,
                gripper.open,
                gripper.closed,
                self.dt,
                recorder._drive_gripper,
            )
        finally:
            recorder.close()

    @property
    def cycle_counts(self):
        """How the fast fidelity played its cycles (None under full dynamics)."""
        return None if self._fast is None else self._fast.counts

    def _gripper_reset_value(self, value: float | None) -> float | None:
        if self._gripper is None:
            return None
        return self.robot.gripper.open if value is None else value

    def _set_joint_state(self, q_arm: np.ndarray, gripper: float | None, gripper_speed: float = 0.0) -> None:
        """Place the arm at rest and the gripper (with its mimic followers) at a value and speed."""
        # one call: each resetJointState updates the whole body (~20 µs a joint, 12 joints on the UR5e)
        joints, values, speeds = list(self._arm), [[float(value)] for value in q_arm], [[0.0]] * len(self._arm)
        if gripper is not None:
            for joint, gain in ((self._gripper, 1.0), *self._gripper_followers):
                joints.append(joint)
                values.append([gain * float(gripper)])
                speeds.append([gain * float(gripper_speed)])
        p.resetJointStatesMultiDof(self.body, joints, values, targetVelocities=speeds, physicsClientId=self.client)

    def _hold(self, q_arm, gripper: float | None) -> None:
        self._hold_arm(q_arm)
        if self._gripper is not None:
            self._drive_gripper(self.robot.gripper.open if gripper is None else gripper)

    def _hold_arm(self, q_arm) -> None:
        self._pending_arm = self._arm_rows = None  # superseded
        p.setJointMotorControlArray(
            self.body,
            self._arm,
            p.POSITION_CONTROL,
            targetPositions=list(q_arm),
            forces=self._efforts,
            positionGains=self._position_gains,
            velocityGains=self._velocity_gains,
            physicsClientId=self.client,
        )

    def _drive_gripper(self, value: float) -> None:
        gripper = self.robot.gripper
        self._gripper_target = float(value)
        p.setJointMotorControl2(
            self.body,
            self._gripper,
            p.POSITION_CONTROL,
            targetPosition=float(value),
            force=self._gripper_force,
            maxVelocity=gripper.max_velocity,
            physicsClientId=self.client,
        )

    def apply_physics(self, change: PhysicsChange) -> None:
        c, quantity, value = self.client, change.quantity, change.value
        with self._lock:
            if quantity == "object_mass":
                body = self.objects[change.target]
                info = p.getDynamicsInfo(body, -1, physicsClientId=c)
                mass, inertia = info[0], info[2]
                p.changeDynamics(
                    body, -1, mass=value, localInertiaDiagonal=[i * value / mass for i in inertia], physicsClientId=c
                )
            elif quantity == "object_friction":
                p.changeDynamics(self.objects[change.target], -1, lateralFriction=value, physicsClientId=c)
            elif quantity == "table_friction":
                p.changeDynamics(self._table_body, -1, lateralFriction=value, physicsClientId=c)
            elif quantity == "arm_damping":
                for joint in self._arm:
                    p.changeDynamics(self.body, joint, jointDamping=value, physicsClientId=c)
            elif quantity == "gripper_force" and self._gripper is not None:
                self._gripper_force = value
                self._drive_gripper(self._gripper_target)  # the drive pushes with the new limit from now on
            else:
                raise BackendError(f"PyBullet cannot set {quantity!r} (known: {', '.join(PHYSICS_QUANTITIES)})")

    # ---------------------------------------------------------------- protocol

    def reset(self, q_arm, gripper, objects) -> None:
        c = self.client
        q_arm = np.asarray(q_arm, float)
        with self._lock:
            # Objects are removed and spawned anew: moving them would keep their
            # contact caches, and the next episode would not replay bit for bit.
            self._remove_objects(self.objects)
            p.restoreState(self._saved, physicsClientId=c)
            gripper_value = self._gripper_reset_value(gripper)
            self._set_joint_state(q_arm, gripper_value)
            self._hold(q_arm, gripper_value)
            self._add_objects(objects)
            if self._fast is not None:
                self._fast.reset(q_arm, gripper_value, has_objects=bool(self.objects))
            self._sim_time = 0.0

    def save_state(self):
        """What a cycle replayed from here needs: PyBullet's state, which keeps no motor targets, with the clock
        and the arm's motor plan (the profile's remaining rows, a command not yet programmed)."""
        with self._lock:
            state = p.saveState(physicsClientId=self.client)
            return state, self._sim_time, self._arm_rows, self._arm_row, self._pending_arm

    def restore_state(self, saved) -> None:
        """Back to a save_state (which stays saved until drop_state)."""
        with self._lock:
            state, self._sim_time, self._arm_rows, self._arm_row, self._pending_arm = saved
            p.restoreState(state, physicsClientId=self.client)

    def drop_state(self, saved) -> None:
        p.removeState(saved[0], physicsClientId=self.client)

    def place_objects(self, objects) -> None:
        """Put the named objects anew, at rest, the arm left as it is: what a person does to a real scene between
        episodes (the twin's scene runs full physics; fast cycles learn of objects only at reset)."""
        if self._fast is not None:
            raise BackendError("objects are placed anew only in full physics; fast cycles place them at reset")
        with self._lock:
            self._remove_objects(objects)
            self._add_objects(objects)

    def place_arm(self, q_arm, gripper: float | None) -> None:
        """Put the arm at rest at `q_arm` and the gripper at `gripper`, held there: what a person does to a real
        arm by hand (freedrive) when it must be brought clear."""
        if self._fast is not None:
            raise BackendError("the arm is placed by hand only in full physics; fast cycles place it at reset")
        with self._lock:
            q_arm = np.asarray(q_arm, float)
            self._set_joint_state(q_arm, gripper)
            self._hold(q_arm, gripper)

    def _remove_objects(self, names) -> None:
        for name in list(names):
            if name in self.objects:
                p.removeBody(self.objects.pop(name), physicsClientId=self.client)

    def _add_objects(self, objects) -> None:
        self.objects.update(scene.add_objects(self.client, self.spec.task.objects, self.task_frame, objects))
        # the bounding sphere of each (cubic) object, and of each fixture's touchable part, for the fast fidelity
        objects = self.spec.task.objects
        self._object_radii = {(body, -1): objects[name].bounding_radius for name, body in self.objects.items()}
        for name, (body, joint) in self._fixture_parts.items():  # the joint's index is its child link's
            self._object_radii[(body, joint)] = self.fixtures[name].touch_radius

    def command_joints(self, q_arm_target, duration: float) -> None:
        # Every joint follows the joint-synchronous profile along the straight joint-space line the safety check
        # proved: its motor is given the line's point and speed at every substep (_substep), as MuJoCo's servos
        # are, and as UR's trajectory controller and xs_sdk move a real arm. A target alone, under a speed limit
        # per motor, let the heavy joints fall behind the light ones under their effort limits: the UR5e left
        # the line by 0.17 rad on the long moves of tests/test_synchronous_motion.py, where its links are proven
        # clear only on it.
        target = np.asarray(q_arm_target, float)
        with self._lock:
            if self._fast is None:
                self._program_arm(target, duration)
                return
            # The fast fidelity plays most cycles without a substep, and a motor's target matters only to
            # substeps: the motors are programmed when a cycle first steps the physics (program_pending_arm).
            self._pending_arm = (target, duration)
            self._fast.commanded_arm(target, duration)

    def _program_arm(self, q_arm_target: np.ndarray, duration: float) -> None:
        """The motor targets of every substep of the motion from where the arm is, laid out once: the last row
        (the target, at rest) holds after it."""
        start = np.array([s[0] for s in p.getJointStates(self.body, self._arm, physicsClientId=self.client)])
        length = synchronous_length(start, q_arm_target, duration, self._speed_limits)
        times = self.dt * np.arange(1, max(1, math.ceil(length / self.dt - 1e-9)) + 1)
        position, velocity, _ = Profile(start, q_arm_target, 0.0, length).at(times)
        self._arm_rows, self._arm_row = (position.tolist(), velocity.tolist()), 0

    def _substep(self) -> None:
        """One physics substep, the arm's motors set to the profile's point and speed at its end first."""
        rows = self._arm_rows
        if rows is not None:
            row = self._arm_row
            self._arm_row = row + 1
            if self._arm_row < len(rows[0]):
                p.setJointMotorControlArray(
                    self.body,
                    self._arm,
                    p.POSITION_CONTROL,
                    targetPositions=rows[0][row],
                    targetVelocities=rows[1][row],
                    forces=self._efforts,
                    positionGains=self._position_gains,
                    velocityGains=self._velocity_gains,
                    physicsClientId=self.client,
                )
            else:  # the profile is over: its target is held as the twin's drivers hold theirs (hold_joints)
                self._arm_rows = None
                self._hold_target(rows[0][row])
        p.stepSimulation(physicsClientId=self.client)

    def hold_joints(self, q_arm_target) -> None:
        """Drive the arm to `q_arm_target` and hold it there with each motor's full speed and effort, with no
        motion profile: what a servo's position loop does once its profile has ended (the twin's drivers, and
        the end of every simulated profile)."""
        with self._lock:
            self._pending_arm = self._arm_rows = None
            self._hold_target(q_arm_target)
            if self._fast is not None:
                self._fast.commanded_arm(q_arm_target, 0.0)

    def _hold_target(self, q_arm_target) -> None:
        """Each motor to its target with its full effort, at most its rated speed: a joint pushed back by what it
        presses returns at that speed."""
        c = self.client
        for joint, target, speed, effort in zip(self._arm, q_arm_target, self._velocities, self._efforts):
            p.setJointMotorControl2(
                self.body,
                joint,
                p.POSITION_CONTROL,
                targetPosition=float(target),
                force=effort,
                maxVelocity=float(speed),
                positionGain=self._position_gain,
                physicsClientId=c,
            )

    def program_pending_arm(self) -> None:
        """Program the arm's motors for the last command, if they do not have it yet (before any substep)."""
        if self._pending_arm is not None:
            target, duration = self._pending_arm
            self._pending_arm = None
            self._program_arm(target, duration)

    def command_gripper(self, value: float) -> None:
        if self._gripper is None:
            raise BackendError(f"robot {self.robot.name!r} has no gripper")
        with self._lock:
            self._drive_gripper(value)
            if self._fast is not None:
                self._fast.commanded_gripper(value)

    def recover(self) -> None:
        pass  # a simulator has no faults to recover from

    def stop(self) -> None:
        """Hold the arm where it is now."""
        with self._lock:
            here = [s[0] for s in p.getJointStates(self.body, self._arm, physicsClientId=self.client)]
            self._hold_arm(here)
            if self._fast is not None:
                self._fast.commanded_arm(here, 0.0)

    def step_timing(self) -> dict[str, float]:
        return {}  # simulated readings are never late

    def advance(self, seconds: float) -> None:
        if self.realtime:
            time.sleep(seconds)
            return
        steps = max(1, round(seconds / self.dt))
        with self._lock:
            if self._fast is not None:
                self._fast.play(seconds, self._object_radii)
            else:
                for _ in range(steps):
                    self._substep()
            self._sim_time += steps * self.dt  # the whole cycle passed, however it was played

    def _run_realtime(self) -> None:
        next_tick = time.perf_counter()
        while not self._closed:
            with self._lock:
                if self._closed:
                    return
                self._substep()
                self._sim_time += self.dt
            next_tick += self.dt
            delay = next_tick - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            else:
                next_tick = time.perf_counter()  # fell behind: do not try to catch up in a burst

    def read_joints(self) -> JointReading:
        with self._lock:
            states = p.getJointStates(self.body, self._state_joints, physicsClientId=self.client)
            stamp = self._sim_time
        position, velocity = np.array([s[0] for s in states]), np.array([s[1] for s in states])
        if self._driver_readings:
            self._driver_readings.apply(position, velocity)
        return JointReading(position, velocity, stamp)

    def read_object(self, name: str) -> ObjectReading:
        joint = None
        with self._lock:
            if name in self._fixture_parts:
                body, index = self._fixture_parts[name]  # the joint's index is its child link's
                state = p.getLinkState(body, index, computeForwardKinematics=1, physicsClientId=self.client)
                position, quaternion = state[4], state[5]
                joint = p.getJointState(body, index, physicsClientId=self.client)[0] - self.fixtures[name].lower
            else:
                position, quaternion = p.getBasePositionAndOrientation(self.objects[name], physicsClientId=self.client)
            stamp = self._sim_time
        task = self.task_frame
        return ObjectReading(task.to_task(position), task.quaternion_to_task(quaternion), stamp, joint)

    def mark_goal(self, position: np.ndarray) -> None:
        with self._lock:
            p.resetBasePositionAndOrientation(
                self._goal_marker,
                self.task_frame.to_world(position).tolist(),
                [0, 0, 0, 1],
                physicsClientId=self.client,
            )

    def render(self, width: int = RENDER_SIZE[0], height: int = RENDER_SIZE[1]) -> np.ndarray:
        with self._lock:
            return scene.render_view(self.client, self.spec.scene.table, width, height)

    def capture(self, camera: CameraSpec) -> CameraFrame:
        with self._lock:
            rgb, depth = scene.capture_frame(self.client, camera, hidden=self._goal_marker)
        return CameraFrame(rgb, depth)

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        if self._thread is not None:
            self._thread.join(timeout=1.0)
        try:
            p.disconnect(self.client)
        except p.error:
            pass
