"""What PyBullet draws and builds around the robot: the scene bodies from primitives (the fixed obstacles, the
task's objects, the goal marker), the gripper's linkage of gear constraints and pad contacts, and the pictures
(the people's view, a scene camera's frame)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pybullet as p

from envfactory.backends.base import BackendError
from envfactory.backends.view import MARKER_RGBA, RENDER_VIEW
from envfactory.geometry.obstacles import Obstacle
from envfactory.schema.models import CameraSpec, ObjectSpec, RobotSpec

# Followers of a mimic joint track their driver through gear constraints (PyBullet ignores URDF <mimic> tags)
GEAR_MAX_FORCE = 1000.0


def _body(
    client: int, shape: int, size: dict, visual_size: dict, position, rgba, mass=0.0, orientation=(0.0, 0.0, 0.0, 1.0)
) -> int:
    """A body of one primitive: PyBullet names a cylinder's height `height` for collision, `length` for sight."""
    collision = p.createCollisionShape(shape, physicsClientId=client, **size)
    visual = p.createVisualShape(shape, rgbaColor=rgba, physicsClientId=client, **visual_size)
    return p.createMultiBody(
        mass, collision, visual, basePosition=list(position), baseOrientation=list(orientation), physicsClientId=client
    )


def _box(client: int, half_extents, position, rgba, mass: float = 0.0, orientation=(0.0, 0.0, 0.0, 1.0)) -> int:
    size = {"halfExtents": list(half_extents)}
    return _body(client, p.GEOM_BOX, size, size, position, rgba, mass, orientation)


def add_obstacles(client: int, obstacles: list[Obstacle]) -> list[int]:
    return [_box(client, list(o.half_extents), list(o.center), o.rgba) for o in obstacles]


def add_object(client: int, spec: ObjectSpec, position, orientation) -> int:
    if spec.shape == "cylinder":
        radius, _, half_height = spec.half_extents
        body = _body(
            client,
            p.GEOM_CYLINDER,
            {"radius": radius, "height": 2 * half_height},
            {"radius": radius, "length": 2 * half_height},
            position,
            spec.rgba,
            spec.mass,
            orientation,
        )
    else:
        body = _box(client, list(spec.half_extents), position, spec.rgba, mass=spec.mass, orientation=orientation)
    p.changeDynamics(
        body,
        -1,
        lateralFriction=spec.friction,
        spinningFriction=spec.spinning_friction,
        rollingFriction=spec.rolling_friction,
        physicsClientId=client,
    )
    return body


def add_objects(client: int, declared: dict[str, ObjectSpec], task_frame, objects) -> dict[str, int]:
    """The task's objects at their (task-frame position, quaternion): their bodies by name."""
    bodies = {}
    for name, (position, quaternion) in objects.items():
        if name not in declared:
            raise BackendError(f"reset places {name!r}, which the task does not declare")
        bodies[name] = add_object(
            client, declared[name], task_frame.to_world(position), task_frame.quaternion_to_world(quaternion)
        )
    return bodies


def add_fixture(client: int, fixture) -> tuple[int, int]:
    """A fixture (geometry.fixtures.FixtureModel) from its URDF, fixed where the spec stands it, its joint at the
    lower limit with its dry friction (a velocity motor held at zero, up to that force) and damping; (body, the
    joint's index, which PyBullet also gives the joint's child link)."""
    x, y, z, w = pin.Quaternion(fixture.rotation).coeffs()
    body = p.loadURDF(
        str(fixture.urdf),
        basePosition=list(map(float, fixture.base)),
        baseOrientation=[x, y, z, w],
        useFixedBase=True,
        flags=p.URDF_USE_INERTIA_FROM_FILE,
        physicsClientId=client,
    )
    names = [
        p.getJointInfo(body, j, physicsClientId=client)[1].decode()
        for j in range(p.getNumJoints(body, physicsClientId=client))
    ]
    if fixture.joint not in names:
        raise BackendError(f"fixture {fixture.name!r}: PyBullet finds no joint {fixture.joint!r} in {fixture.urdf}")
    index = names.index(fixture.joint)
    p.resetJointState(body, index, fixture.lower, physicsClientId=client)
    p.setJointMotorControl2(
        body, index, p.VELOCITY_CONTROL, targetVelocity=0.0, force=fixture.friction, physicsClientId=client
    )
    p.changeDynamics(body, index, jointDamping=fixture.damping, physicsClientId=client)
    return body, index


def add_marker(client: int, position, radius: float = 0.025) -> int:
    """A see-through sphere with no collision shape: shows the goal, touches nothing."""
    visual = p.createVisualShape(p.GEOM_SPHERE, radius=radius, rgbaColor=MARKER_RGBA, physicsClientId=client)
    return p.createMultiBody(0.0, -1, visual, basePosition=list(position), physicsClientId=client)


def link_gripper(client: int, body: int, robot: RobotSpec, index: dict[str, int], link_index: dict[str, int]):
    """The gripper's mimic joints held to its driven joint by gear constraints (PyBullet ignores URDF mimic
    tags), and its pads' contact parameters; the (follower joint, gain) pairs."""
    gripper = robot.gripper
    driven = index[gripper.joint]
    followers = [(index[name], gain) for name, gain in gripper.mimic.items()]
    for follower, gain in followers:
        constraint = p.createConstraint(
            body, driven, body, follower, p.JOINT_GEAR, [1, 0, 0], [0, 0, 0], [0, 0, 0], physicsClientId=client
        )
        p.changeConstraint(constraint, gearRatio=-1.0 / gain, maxForce=GEAR_MAX_FORCE, erp=0.8, physicsClientId=client)
    pads = gripper.pads
    for link in pads.links:
        if link not in link_index:
            raise BackendError(f"robot {robot.name!r}: gripper.pads names no link {link!r}")
        p.changeDynamics(
            body,
            link_index[link],
            lateralFriction=pads.lateral_friction,
            spinningFriction=pads.spinning_friction,
            rollingFriction=pads.rolling_friction,
            frictionAnchor=int(pads.friction_anchor),
            physicsClientId=client,
        )
    return followers


def _pixels(client: int, width: int, height: int, view, projection):
    _, _, rgba, depth_buffer, _ = p.getCameraImage(
        width, height, view, projection, renderer=p.ER_TINY_RENDERER, physicsClientId=client
    )
    return np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)[:, :, :3].copy(), depth_buffer


def render_view(client: int, table, width: int, height: int) -> np.ndarray:
    """The people's picture of the scene (backends/view.py's view, as MuJoCo draws it)."""
    view = p.computeViewMatrixFromYawPitchRoll(
        cameraTargetPosition=RENDER_VIEW.target(table),
        distance=RENDER_VIEW.distance,
        yaw=RENDER_VIEW.yaw,
        pitch=RENDER_VIEW.pitch,
        roll=0,
        upAxisIndex=2,
    )
    projection = p.computeProjectionMatrixFOV(fov=55, aspect=width / height, nearVal=0.05, farVal=6.0)
    return _pixels(client, width, height, view, projection)[0]


def capture_frame(client: int, camera: CameraSpec, hidden: int) -> tuple[np.ndarray, np.ndarray]:
    """A scene camera's RGB and depth (metres along the view axis), with the body `hidden` (the goal marker:
    it is for people watching, the policy's camera must not see the goal) out of the picture."""
    width, height = camera.width, camera.height
    view = p.computeViewMatrix(
        cameraEyePosition=list(camera.eye), cameraTargetPosition=list(camera.target), cameraUpVector=[0, 0, 1]
    )
    projection = p.computeProjectionMatrixFOV(
        fov=camera.fov, aspect=width / height, nearVal=camera.near, farVal=camera.far
    )
    p.changeVisualShape(hidden, -1, rgbaColor=[0, 0, 0, 0], physicsClientId=client)
    rgb, depth_buffer = _pixels(client, width, height, view, projection)
    p.changeVisualShape(hidden, -1, rgbaColor=MARKER_RGBA, physicsClientId=client)
    # the buffer holds OpenGL depth in [0, 1]; turn it back into metres
    buffer = np.asarray(depth_buffer, dtype=np.float32).reshape(height, width)
    near, far = camera.near, camera.far
    return rgb, (far * near / (far - (far - near) * buffer)).astype(np.float32)
