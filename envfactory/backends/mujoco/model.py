"""The MuJoCo model of a spec: the same assembled URDF PyBullet loads, converted by MuJoCo's URDF import,
placed at the robot's mount inside the scene the safety check guards, with the task's objects, a goal
marker and the scene camera. Nothing is written per robot: every number comes from the specs.

Choices where MuJoCo and PyBullet differ, each a setting of the model built here:
- mimic joints are equality constraints from the robot YAML's `gripper.mimic` (the URDF's own mimic tags,
  which the import also turns into constraints, are dropped so that one source decides), as stiff as the
  timestep allows: at MuJoCo's default softness a squeezing Robotiq linkage gave way 0.21 rad, its pads
  tilted 25° and held the cube on one point each, about which it swung on and on;
- the arm's bodies are gravity-compensated, as UR's controller and xs_sdk compensate the arm's weight, so
  the position servos track the commanded profile instead of sagging under load;
- the robot does not collide with itself (the safety check keeps its links apart; the gripper's linkage
  overlaps by design, as in PyBullet), only with the scene and the objects;
- friction: elliptic cones with impratio 10 and a no-slip pass, so a grasped cube does not creep out of the pads;
- two surfaces in contact rub with the product of their coefficients, as in PyBullet (MuJoCo's own rule takes
  the larger: a cube of friction 0.6 would grip the table at 0.6, not 0.3, and tip over under a push where it
  slides in PyBullet), so every contact of an object is an explicit pair carrying the product; a surface the
  specs give no friction has PyBullet's default, SURFACE_FRICTION.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin

from envfactory.backends.view import MARKER_RGBA
from envfactory.geometry.frames import base_rotation
from envfactory.geometry.obstacles import FLOOR, SURFACE_FRICTION, scene_obstacles
from envfactory.schema.models import CameraSpec, ComposedSpec

ROBOT_PREFIX = "robot/"
# contype/conaffinity bits: robot geoms touch the scene and objects, never each other
ROBOT_TYPE, ROBOT_AFFINITY = 2, 1
WORLD_TYPE, WORLD_AFFINITY = 1, 3
SERVO_STIFFNESS_ERROR = 0.01  # rad (or m): the position error at which a servo pushes its full effort
# Reflected rotor inertia of a joint's drive, in proportion to its effort (a stronger joint has a bigger motor
# behind a gearbox); it is what keeps a stiff servo on a light link stable at the engine's timestep.
ARMATURE_PER_EFFORT = 1e-3  # kg m^2 per N m (kg per N on a slide)
# A joint the specs do not drive (the VX300S's gripper motor horn) is held by PyBullet's default velocity motors;
# here a damper stops it, or the arm's swings would spin it on forever and the scene would never be at rest.
UNDRIVEN_DAMPING = 0.01  # N m s / rad
# The mimic constraints' time constant (s; never under two timesteps, below which MuJoCo's integration is
# unstable) and impedance: stiff enough that a UR5e squeezing its cube keeps the linkage within 0.03 rad and
# the pads flat on it, so the held cube neither swings in the hand nor drifts more than 4 mm in the hold of
# tests/test_manipulation.py on MuJoCo.
MIMIC_TIMECONST = 0.008
MIMIC_IMPEDANCE = (0.99, 0.99, 0.001, 0.5, 2.0)
CAMERA = "scene_camera"


@dataclass(frozen=True)
class Handles:
    """Where each thing the backend reads or drives sits in the compiled model."""

    arm_qpos: np.ndarray
    arm_dof: np.ndarray
    arm_actuators: np.ndarray
    state_qpos: np.ndarray  # the /joint_states entries, in order
    state_dof: np.ndarray
    gripper_qpos: int | None
    gripper_dof: int | None
    gripper_actuator: int | None
    followers: tuple[tuple[int, int, float], ...]  # (qpos address, dof address, gain) of each mimic follower
    object_qpos: dict[str, int]  # freejoint qpos address of each object
    object_dof: dict[str, int]  # its first dof address
    object_body: dict[str, int]
    marker_mocap: int
    # each fixture's joint: (qpos address, dof address, its lower limit), and the body its reading is of
    fixture_joint: dict[str, tuple[int, int, float]] = field(default_factory=dict)
    fixture_body: dict[str, int] = field(default_factory=dict)
    # per contact pair (in the model's order), the two surfaces it joins, and each surface's friction: what
    # a randomized friction recomputes the pair's product from
    pair_surfaces: tuple[tuple[str, str], ...] = ()
    surface_friction: dict[str, tuple[float, float, float]] | None = None


def _wxyz(rotation: np.ndarray) -> list[float]:
    x, y, z, w = pin.Quaternion(rotation).coeffs()
    return [float(w), float(x), float(y), float(z)]


def _friction_condim(lateral: float, spinning: float, rolling: float) -> int:
    return 6 if rolling > 0 else 4 if spinning > 0 else 3


def _pair_friction(one: tuple[float, float, float], other: tuple[float, float, float]) -> tuple[float, ...]:
    """Lateral, spinning and rolling friction of two surfaces in contact: the products, as PyBullet combines."""
    return tuple(a * b for a, b in zip(one, other))


def _camera_axes(camera: CameraSpec) -> list[float]:
    """MuJoCo's xyaxes of a camera at `eye` looking at `target` with z up in the image."""
    forward = np.subtract(camera.target, camera.eye)
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    return [*right, *up]


def build(spec: ComposedSpec, urdf_path: Path, fixtures: dict | None = None) -> tuple[mujoco.MjModel, Handles]:
    robot_spec = spec.robot
    world = mujoco.MjSpec()
    world.option.timestep = 1.0 / spec.sim.mujoco.physics_hz
    world.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    world.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    world.option.impratio = 10.0
    world.option.iterations = spec.sim.mujoco.solver_iterations
    world.option.noslip_iterations = spec.sim.mujoco.noslip_iterations
    surfaces: dict[str, tuple[float, float, float]] = {}  # every geom an object can touch, and its friction
    pair_surfaces: list[tuple[str, str]] = []
    for obstacle in scene_obstacles(spec):
        name = f"obstacle:{obstacle.name}"
        if obstacle.name == FLOOR:
            # a plane at the floor box's top: a half-space, which an object falling off the table at 4 m/s
            # cannot pass through as it passed through the 2 cm box under MuJoCo's soft contact
            shape = {"type": mujoco.mjtGeom.mjGEOM_PLANE, "size": [*obstacle.half_extents[:2], 0.1]}
            shape["pos"] = [*obstacle.center[:2], float(obstacle.high[2])]
        else:
            shape = {
                "type": mujoco.mjtGeom.mjGEOM_BOX,
                "size": list(obstacle.half_extents),
                "pos": list(obstacle.center),
            }
        world.worldbody.add_geom(
            name=name, rgba=list(obstacle.rgba), contype=WORLD_TYPE, conaffinity=WORLD_AFFINITY, **shape
        )
        surfaces[name] = SURFACE_FRICTION

    robot = mujoco.MjSpec.from_file(str(urdf_path))
    for equality in list(robot.equalities):
        robot.delete(equality)
    mount = world.worldbody.add_body(
        name="robot_mount", pos=list(robot_spec.mount), quat=_wxyz(base_rotation(robot_spec))
    )
    world.attach(robot, frame=mount.add_frame(), prefix=ROBOT_PREFIX)
    pads = set(robot_spec.gripper.pads.links) if robot_spec.gripper is not None else set()
    for body in mount.find_all(mujoco.mjtObj.mjOBJ_BODY):
        body.gravcomp = 1.0
        for index, geom in enumerate(body.geoms):
            if geom.contype == 0 and geom.conaffinity == 0:
                continue  # a visual geom
            geom.contype, geom.conaffinity = ROBOT_TYPE, ROBOT_AFFINITY
            geom.name = geom.name or f"{body.name}#{index}"
            surfaces[geom.name] = SURFACE_FRICTION
            if body.name.removeprefix(ROBOT_PREFIX) in pads:
                contact = robot_spec.gripper.pads
                surfaces[geom.name] = (contact.lateral_friction, contact.spinning_friction, contact.rolling_friction)

    for joint, effort in zip(robot_spec.arm_joints, robot_spec.arm_efforts):
        _servo(world, joint.name, effort)
    driven = {ROBOT_PREFIX + joint.name for joint in robot_spec.arm_joints}
    if robot_spec.gripper is not None:
        driven |= {ROBOT_PREFIX + name for name in (robot_spec.gripper.joint, *robot_spec.gripper.mimic)}
    for joint in mount.find_all(mujoco.mjtObj.mjOBJ_JOINT):
        if joint.name not in driven:
            joint.damping = [UNDRIVEN_DAMPING, 0.0, 0.0]
    gripper = robot_spec.gripper
    if gripper is not None:
        _servo(world, gripper.joint, gripper.force)
        for follower, gain in gripper.mimic.items():
            world.add_equality(
                type=mujoco.mjtEq.mjEQ_JOINT,
                name1=ROBOT_PREFIX + follower,
                name2=ROBOT_PREFIX + gripper.joint,
                data=[0.0, gain] + [0.0] * 10,
                solref=[max(MIMIC_TIMECONST, 2 * world.option.timestep), 1.0],
                solimp=list(MIMIC_IMPEDANCE),
            )

    fixtures = fixtures or {}
    for fixture in fixtures.values():
        _add_fixture(world, fixture, surfaces)

    for index, (name, obj) in enumerate(spec.task.objects.items()):
        body = world.worldbody.add_body(name=f"object:{name}", pos=[0.0, 0.0, -10.0 - index])
        body.add_freejoint(name=f"object:{name}")
        # no contact of its own: each is an explicit pair below, with the product of the two frictions
        body.add_geom(
            name=f"object:{name}",
            # MuJoCo's cylinder size is its radius and half height
            type=mujoco.mjtGeom.mjGEOM_CYLINDER if obj.shape == "cylinder" else mujoco.mjtGeom.mjGEOM_BOX,
            size=[obj.half_extents[0], obj.half_extents[2], 0.0] if obj.shape == "cylinder" else list(obj.half_extents),
            mass=obj.mass,
            rgba=list(obj.rgba),
            contype=0,
            conaffinity=0,
        )
        friction = (obj.friction, obj.spinning_friction, obj.rolling_friction)
        for other, other_friction in surfaces.items():
            lateral, spinning, rolling = _pair_friction(friction, other_friction)
            # MuJoCo's five: two tangential, spinning, two rolling
            world.add_pair(
                geomname1=f"object:{name}",
                geomname2=other,
                friction=[lateral, lateral, spinning, rolling, rolling],
                condim=_friction_condim(lateral, spinning, rolling),
            )
            pair_surfaces.append((f"object:{name}", other))
        surfaces[f"object:{name}"] = friction
    marker = world.worldbody.add_body(name="goal_marker", mocap=True, pos=[0.0, 0.0, -10.0])
    marker.add_geom(
        type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.025, 0, 0], rgba=list(MARKER_RGBA), contype=0, conaffinity=0, group=3
    )
    camera = spec.scene.camera
    if camera is not None:
        world.worldbody.add_camera(name=CAMERA, pos=list(camera.eye), fovy=camera.fov)
        world.cameras[-1].alt.type = mujoco.mjtOrientation.mjORIENTATION_XYAXES
        world.cameras[-1].alt.xyaxes = _camera_axes(camera)
    model = world.compile()
    handles = replace(
        _handles(model, spec),
        pair_surfaces=tuple(pair_surfaces),
        surface_friction=surfaces,
        fixture_joint={
            name: (
                int(model.joint(f"{_fixture_prefix(name)}{f.joint}").qposadr[0]),
                int(model.joint(f"{_fixture_prefix(name)}{f.joint}").dofadr[0]),
                f.lower,
            )
            for name, f in fixtures.items()
        },
        fixture_body={
            name: int(model.joint(f"{_fixture_prefix(name)}{f.joint}").bodyid[0]) for name, f in fixtures.items()
        },
    )
    return model, handles


def _fixture_prefix(name: str) -> str:
    return f"fixture:{name}/"


def _add_fixture(world: mujoco.MjSpec, fixture, surfaces: dict) -> None:
    """A fixture (geometry.fixtures.FixtureModel) from its URDF by MuJoCo's import, fixed where the spec stands it:
    scene geoms (the robot touches them, objects through explicit pairs) with PyBullet's default friction, its
    joint with the fixture's dry friction (frictionloss) and damping."""
    part = mujoco.MjSpec.from_file(str(fixture.urdf))
    mount = world.worldbody.add_body(
        name=f"fixture:{fixture.name}", pos=list(map(float, fixture.base)), quat=_wxyz(fixture.rotation)
    )
    world.attach(part, frame=mount.add_frame(), prefix=_fixture_prefix(fixture.name))
    for body in [mount, *mount.find_all(mujoco.mjtObj.mjOBJ_BODY)]:
        for index, geom in enumerate(body.geoms):
            geom.contype, geom.conaffinity = WORLD_TYPE, WORLD_AFFINITY
            geom.name = geom.name or f"{body.name or mount.name}#{index}"
            surfaces[geom.name] = SURFACE_FRICTION
    joint = world.joint(_fixture_prefix(fixture.name) + fixture.joint)
    joint.frictionloss = fixture.friction
    joint.damping = [fixture.damping, 0.0, 0.0]


def _servo(world: mujoco.MjSpec, joint: str, effort: float) -> None:
    """A position servo on a joint: full effort at SERVO_STIFFNESS_ERROR, critically damped. The spec's effort is
    its only limit, as in PyBullet: MuJoCo's URDF import makes the URDF's effort the joint's actuator force range,
    which capped servos below the spec's effort without a word (one gripper's jaws at half their force, so a held
    cube slipped out during a turn it survives in PyBullet; another's fingers at under a third; wrists at a fifth)."""
    actuator = world.add_actuator(name=f"servo:{joint}", target=ROBOT_PREFIX + joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
    actuator.set_to_position(kp=effort / SERVO_STIFFNESS_ERROR, dampratio=1.0)
    actuator.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
    actuator.forcerange = [-effort, effort]
    driven = world.joint(ROBOT_PREFIX + joint)
    driven.armature = effort * ARMATURE_PER_EFFORT
    driven.actfrclimited = mujoco.mjtLimited.mjLIMITED_FALSE


def _handles(model: mujoco.MjModel, spec: ComposedSpec) -> Handles:
    robot = spec.robot

    def joint(name: str):
        return model.joint(ROBOT_PREFIX + name)

    gripper = robot.gripper
    return Handles(
        arm_qpos=np.array([joint(j.name).qposadr[0] for j in robot.arm_joints]),
        arm_dof=np.array([joint(j.name).dofadr[0] for j in robot.arm_joints]),
        arm_actuators=np.array([model.actuator(f"servo:{j.name}").id for j in robot.arm_joints]),
        state_qpos=np.array([joint(e.urdf_joint).qposadr[0] for e in robot.joint_states]),
        state_dof=np.array([joint(e.urdf_joint).dofadr[0] for e in robot.joint_states]),
        gripper_qpos=None if gripper is None else int(joint(gripper.joint).qposadr[0]),
        gripper_dof=None if gripper is None else int(joint(gripper.joint).dofadr[0]),
        gripper_actuator=None if gripper is None else model.actuator(f"servo:{gripper.joint}").id,
        followers=()
        if gripper is None
        else tuple(
            (int(joint(name).qposadr[0]), int(joint(name).dofadr[0]), gain) for name, gain in gripper.mimic.items()
        ),
        object_qpos={name: int(model.joint(f"object:{name}").qposadr[0]) for name in spec.task.objects},
        object_dof={name: int(model.joint(f"object:{name}").dofadr[0]) for name in spec.task.objects},
        object_body={name: model.body(f"object:{name}").id for name in spec.task.objects},
        marker_mocap=int(model.body("goal_marker").mocapid[0]),
    )
