"""The embedded MuJoCo backend: headless, the same Backend protocol as PyBullet's, built from the same specs.
How a cycle is played (the profiles, the servos, the fast fidelity's shortcuts) is fast_cycles.py's."""

from __future__ import annotations

import time
import warnings

import mujoco
import numpy as np

from envfactory.backends.at_rest import CycleCounts
from envfactory.backends.base import (
    PHYSICS_QUANTITIES,
    BackendError,
    CameraFrame,
    JointReading,
    ObjectReading,
    PhysicsChange,
)
from envfactory.backends.driver_readings import DriverReadings
from envfactory.backends.mujoco.fast_cycles import FastCycles
from envfactory.backends.mujoco.model import CAMERA, Handles, build
from envfactory.backends.view import RENDER_SIZE, RENDER_VIEW
from envfactory.geometry.frames import TaskFrame
from envfactory.geometry.obstacles import TABLE_TOP
from envfactory.schema.models import CameraSpec, ComposedSpec

_render_failure: str | None = None  # why this process cannot render, once a try has shown it
RENDER_HELP = (
    "MuJoCo renders through OpenGL: set MUJOCO_GL=egl (needs libEGL and a GPU driver) or "
    "MUJOCO_GL=osmesa (needs libOSMesa, e.g. Debian's libosmesa6) before the first import of mujoco"
)


class MujocoBackend:
    """The Backend protocol on MuJoCo: one model and data per env, built from the robot's URDF and the scene,
    its cycles played by FastCycles (the arm's joint-synchronous profile tracked by position servos; with the
    fast fidelity, cycles that cannot touch an object played without dynamics). Not thread-safe: one env, one
    thread."""

    teleports_on_reset = True  # reset sets the joints directly; no path is driven

    def __init__(
        self,
        spec: ComposedSpec,
        urdf_path,
        task_frame: TaskFrame,
        render_mode: str | None = None,
        fixtures: dict | None = None,
        built: tuple[mujoco.MjModel, Handles] | None = None,
    ):
        """`built`: another backend's `built` of the same spec, whose model this one runs on with its own data
        (RobotVectorEnv's sharing); only for a model nothing rewrites, as randomized physics does."""
        if spec.env.gui or render_mode == "human":
            raise BackendError(
                "the MuJoCo engine runs headless: a GUI (gui=True, render_mode='human') is "
                "PyBullet's (engine='pybullet')"
            )
        self.spec = spec
        self.robot = spec.robot
        self.task_frame = task_frame
        self.model, self.handles = built if built is not None else build(spec, urdf_path, fixtures)
        self.data = mujoco.MjData(self.model)
        self.cycles = FastCycles(spec, self.model, self.data, self.handles, fixtures)
        self._driver_readings = DriverReadings(self.robot)
        self._renderers: dict[tuple[int, int], mujoco.Renderer] = {}
        self._realtime = spec.env.timing.realtime
        # what randomized physics scales from and recombines: each object's mass and inertia as built, and the
        # friction of every surface an object can touch
        self._built_mass = {
            body: (float(self.model.body_mass[body]), self.model.body_inertia[body].copy())
            for body in self.handles.object_body.values()
        }
        self._friction = dict(self.handles.surface_friction or {})
        self._scratch = mujoco.MjData(self.model)  # for mj_setConst after a mass changes
        camera = spec.scene.camera
        if spec.env.observation.camera_images and camera is not None:
            self._renderer(camera.width, camera.height)  # images are part of every observation: fail at make

    @property
    def built(self) -> tuple[mujoco.MjModel, Handles]:
        return self.model, self.handles

    # ---------------------------------------------------------------- protocol

    def attach_geometry(self, collision) -> None:
        """The safety check's collision model: with `sim.fidelity: fast` it proves motions clear of the
        objects, so those cycles are played without dynamics (fast_cycles.py)."""
        self.cycles.attach(collision)

    @property
    def cycle_counts(self) -> CycleCounts | None:
        """How the fast fidelity played its cycles (None under full dynamics)."""
        return self.cycles.counts if self.cycles.fast else None

    def reset(self, q_arm, gripper, objects) -> None:
        model, data, handles = self.model, self.data, self.handles
        mujoco.mj_resetData(model, data)
        self.cycles.reset(np.asarray(q_arm, float))
        if handles.gripper_qpos is not None:
            value = self.robot.gripper.open if gripper is None else float(gripper)
            self.cycles.place_gripper(value)
            data.ctrl[handles.gripper_actuator] = value
        for name, (position, quaternion) in objects.items():
            if name not in handles.object_qpos:
                raise BackendError(f"reset places {name!r}, which the task does not declare")
            x, y, z, w = self.task_frame.quaternion_to_world(quaternion)
            address = handles.object_qpos[name]
            data.qpos[address : address + 7] = [*self.task_frame.to_world(position), w, x, y, z]
        for address, _, lower in handles.fixture_joint.values():  # every fixture closed
            data.qpos[address] = lower
        mujoco.mj_forward(model, data)

    def command_joints(self, q_arm_target, duration: float) -> None:
        self.cycles.commanded_arm(q_arm_target, duration)

    def command_gripper(self, value: float) -> None:
        if self.handles.gripper_actuator is None:
            raise BackendError(f"robot {self.robot.name!r} has no gripper")
        self.cycles.commanded_gripper(value)

    def recover(self) -> None:
        pass  # a simulator has no faults to recover from

    def stop(self) -> None:
        """Hold the arm where it is now."""
        self.cycles.hold()

    def apply_physics(self, change: PhysicsChange) -> None:
        model, handles, quantity, value = self.model, self.handles, change.quantity, change.value
        if quantity == "object_mass":
            body = handles.object_body[change.target]
            mass, inertia = self._built_mass[body]
            model.body_mass[body] = value
            model.body_inertia[body] = inertia * (value / mass)
            # the solver scales each constraint's softness by the inverse weights taken at build: a lighter
            # body left with its old ones meets too stiff a contact (measured: a 0.05 kg cube blew up)
            mujoco.mj_setConst(model, self._scratch)
        elif quantity in ("object_friction", "table_friction"):
            surface = f"object:{change.target}" if quantity == "object_friction" else f"obstacle:{TABLE_TOP}"
            self._friction[surface] = (value, *self._friction[surface][1:])
            for index, (one, other) in enumerate(handles.pair_surfaces):
                if surface in (one, other):  # the pair rubs with the product, as it was built (model.py)
                    model.pair_friction[index, :2] = self._friction[one][0] * self._friction[other][0]
        elif quantity == "arm_damping":
            model.dof_damping[handles.arm_dof] = value
        elif quantity == "gripper_force" and handles.gripper_actuator is not None:
            model.actuator_forcerange[handles.gripper_actuator] = [-value, value]
        else:
            raise BackendError(f"MuJoCo cannot set {quantity!r} (known: {', '.join(PHYSICS_QUANTITIES)})")

    def step_timing(self) -> dict[str, float]:
        return {}  # simulated readings are never late

    def advance(self, seconds: float) -> None:
        """Simulate `seconds`; in realtime mode, also let that long pass on the wall clock, so that an episode
        takes as long as on the real arm (the engine still simulates the cycle at once: nothing moves between
        steps, unlike PyBullet's realtime thread)."""
        if not self._realtime:
            self.cycles.play(seconds)
            return
        deadline = time.perf_counter() + seconds
        self.cycles.play(seconds)
        time.sleep(max(0.0, deadline - time.perf_counter()))

    def read_joints(self) -> JointReading:
        # (indexing by an address array copies already)
        position, velocity = self.data.qpos[self.handles.state_qpos], self.data.qvel[self.handles.state_dof]
        if self._driver_readings:
            self._driver_readings.apply(position, velocity)
        return JointReading(position, velocity, self.cycles.sim_time)

    def read_object(self, name: str) -> ObjectReading:
        handles, joint = self.handles, None
        if name in handles.fixture_body:
            body = handles.fixture_body[name]
            address, _, lower = handles.fixture_joint[name]
            joint = float(self.data.qpos[address]) - lower
        else:
            body = handles.object_body[name]
        w, x, y, z = self.data.xquat[body]
        return ObjectReading(
            self.task_frame.to_task(self.data.xpos[body].copy()),
            self.task_frame.quaternion_to_task([x, y, z, w]),
            self.cycles.sim_time,
            joint,
        )

    def mark_goal(self, position: np.ndarray) -> None:
        self.data.mocap_pos[self.handles.marker_mocap] = self.task_frame.to_world(position)

    def _renderer(self, width: int, height: int) -> mujoco.Renderer:
        global _render_failure
        key = (width, height)
        if key not in self._renderers:
            # a second try after a failed one aborts the whole process inside MuJoCo's GL setup: never retry
            if _render_failure is not None:
                raise BackendError(_render_failure)
            try:
                with warnings.catch_warnings():  # GLFW's own complaints about the missing display
                    warnings.simplefilter("ignore")
                    self._renderers[key] = mujoco.Renderer(self.model, height, width)
            except Exception as exc:  # no OpenGL context of any kind on this machine
                _render_failure = f"MuJoCo cannot render here ({exc}): {RENDER_HELP}"
                raise BackendError(_render_failure) from None
        return self._renderers[key]

    def render(self, width: int = RENDER_SIZE[0], height: int = RENDER_SIZE[1]) -> np.ndarray:
        renderer = self._renderer(width, height)
        camera = mujoco.MjvCamera()
        camera.lookat[:] = RENDER_VIEW.target(self.spec.scene.table)
        camera.distance, camera.azimuth, camera.elevation = (
            RENDER_VIEW.distance,
            RENDER_VIEW.yaw + 180.0,
            RENDER_VIEW.pitch,
        )
        renderer.update_scene(self.data, camera)
        return renderer.render().copy()

    def capture(self, camera: CameraSpec) -> CameraFrame:
        renderer = self._renderer(camera.width, camera.height)
        options = mujoco.MjvOption()
        options.geomgroup[3] = 0  # the goal marker is for people watching: the policy's camera must not see it
        renderer.update_scene(self.data, CAMERA, options)
        rgb = renderer.render().copy()
        renderer.enable_depth_rendering()
        renderer.update_scene(self.data, CAMERA, options)
        depth = renderer.render().astype(np.float32)
        renderer.disable_depth_rendering()
        return CameraFrame(rgb, depth)

    def close(self) -> None:
        self.cycles.close()
        for renderer in self._renderers.values():
            renderer.close()
        self._renderers.clear()
