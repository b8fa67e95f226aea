"""Reading the makers' robot models (reference data outside the repository) for the checks of our URDFs.

Where they are: $ENVFACTORY_ROBOT_MODELS, else ../shared/robot-models beside the repository. One folder per
robot, named as our robot YAML's `name`, holding <name>.urdf with meshes relative to it.
"""

from __future__ import annotations

import os
import struct
import xml.etree.ElementTree as ET
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin

ROOT = Path(__file__).resolve().parents[2]  # the repository


def models_folder() -> Path | None:
    configured = os.environ.get("ENVFACTORY_ROBOT_MODELS")
    folder = Path(configured) if configured else ROOT.parent / "shared" / "robot-models"
    return folder if folder.is_dir() else None


def _origin(element) -> pin.SE3:
    origin = element.find("origin") if element is not None else None
    xyz = [float(x) for x in (origin.get("xyz") or "0 0 0").split()] if origin is not None else [0.0] * 3
    rpy = [float(x) for x in (origin.get("rpy") or "0 0 0").split()] if origin is not None else [0.0] * 3
    return pin.SE3(pin.rpy.rpyToMatrix(*rpy), np.array(xyz))


def read_stl(path: Path) -> np.ndarray:
    """Triangle corners, three rows per triangle, in the file's units."""
    data = path.read_bytes()
    count = struct.unpack("<I", data[80:84])[0] if len(data) >= 84 else 0
    if len(data) == 84 + 50 * count:  # binary (an ASCII file cannot have exactly this length by chance)
        rows = np.frombuffer(data[84:], dtype=np.dtype([("normal", "<3f4"), ("corners", "<9f4"), ("attr", "<u2")]))
        return rows["corners"].reshape(-1, 3).astype(float)
    corners = [line.split()[1:4] for line in data.decode("ascii").splitlines() if line.strip().startswith("vertex")]
    return np.array(corners, dtype=float)


def surface_points(corners: np.ndarray, spacing: float = 0.004) -> np.ndarray:
    """The corners and points spread over every triangle, at most `spacing` apart along its longest edge:
    a long flat face with vertices only at its ends is checked along its whole length."""
    triangles = corners.reshape(-1, 3, 3)
    longest = np.max(np.linalg.norm(triangles - np.roll(triangles, 1, axis=1), axis=2), axis=1)
    steps = np.maximum(1, np.ceil(longest / spacing)).astype(int)
    points = [corners]
    for n in np.unique(steps[steps > 1]):
        i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1))
        keep = i + j <= n
        weights = np.stack([i[keep], j[keep], n - i[keep] - j[keep]], axis=1) / n
        points.append(np.einsum("pk,tkd->tpd", weights, triangles[steps == n]).reshape(-1, 3))
    return np.vstack(points)


def _link_meshes(urdf: Path, strip: str = "", links: set[str] | None = None):
    """(link name less `strip`, [mesh triangle corners (3n, 3) in the link frame, one array per collision
    mesh]) of every link with a collision mesh; only the named links, if given."""
    for link in ET.parse(urdf).getroot().findall("link"):
        name = link.get("name").removeprefix(strip)
        if links is not None and name not in links:
            continue
        meshes = []
        for collision in link.findall("collision"):
            mesh = collision.find("geometry/mesh")
            if mesh is None:
                continue
            scale = np.array([float(s) for s in (mesh.get("scale") or "1 1 1").split()])
            placement = _origin(collision)
            corners = read_stl(urdf.parent / mesh.get("filename")) * scale
            meshes.append(corners @ placement.rotation.T + placement.translation)
        if meshes:
            yield name, meshes


def link_mesh_points(
    urdf: Path, strip: str = "", spacing: float = 0.004, links: set[str] | None = None
) -> dict[str, np.ndarray]:
    """Each link's collision mesh surface in the link frame (points at most `spacing` apart), by link name
    less `strip`; only the named links, if given."""
    return {
        name: np.vstack([surface_points(corners, spacing) for corners in meshes])
        for name, meshes in _link_meshes(urdf, strip, links)
    }


def link_primitives(urdf: Path) -> dict[str, list[tuple[str, pin.SE3, np.ndarray]]]:
    """Each link's collision primitives: (kind, placement in the link frame, size), size being the box's
    edges, the cylinder's (radius, length) or the sphere's (radius,)."""
    result = {}
    for link in ET.parse(urdf).getroot().findall("link"):
        shapes = []
        for collision in link.findall("collision"):
            geometry = collision.find("geometry")[0]
            if geometry.tag == "box":
                size = np.array([float(s) for s in geometry.get("size").split()])
            elif geometry.tag == "cylinder":
                size = np.array([float(geometry.get("radius")), float(geometry.get("length"))])
            elif geometry.tag == "sphere":
                size = np.array([float(geometry.get("radius"))])
            else:
                raise ValueError(
                    f"{urdf.name}: link {link.get('name')} has a {geometry.tag} collision, not a primitive"
                )
            shapes.append((geometry.tag, _origin(collision), size))
        result[link.get("name")] = shapes
    return result


def outside_distance(points: np.ndarray, kind: str, placement: pin.SE3, size: np.ndarray) -> np.ndarray:
    """How far each point (link frame) lies outside one primitive; 0 inside."""
    local = (points - placement.translation) @ placement.rotation
    if kind == "box":
        return np.linalg.norm(np.maximum(np.abs(local) - size / 2, 0.0), axis=1)
    if kind == "cylinder":  # axis along local z
        radial = np.maximum(np.linalg.norm(local[:, :2], axis=1) - size[0], 0.0)
        axial = np.maximum(np.abs(local[:, 2]) - size[1] / 2, 0.0)
        return np.hypot(radial, axial)
    return np.maximum(np.linalg.norm(local, axis=1) - size[0], 0.0)


def configuration(model: pin.Model, values: dict[str, float]) -> np.ndarray:
    """A Pinocchio configuration from joint values by name (a continuous joint takes cos, sin)."""
    q = pin.neutral(model)
    for joint_id in range(1, model.njoints):
        name, joint = model.names[joint_id], model.joints[joint_id]
        value = values.get(name, 0.0)
        if joint.nq == 2:
            q[joint.idx_q : joint.idx_q + 2] = np.cos(value), np.sin(value)
        else:
            q[joint.idx_q] = value
    return q


def link_triangles(urdf: Path, strip: str = "") -> dict[str, np.ndarray]:
    """Each link's collision mesh as triangles (n, 3, 3) in the link frame, by link name less `strip`."""
    return {
        name: np.vstack([corners.reshape(-1, 3, 3) for corners in meshes]) for name, meshes in _link_meshes(urdf, strip)
    }


class MakerMeshes:
    """A maker's robot posed by forward kinematics of the maker's own URDF, its links' meshes measured as
    meshes: coal's distance between triangle soups (not their convex hulls, which would close the Ned2's
    open fork and the elbow's L), 0 where their triangles cross."""

    def __init__(self, urdf: Path, strip: str = ""):
        self.model = pin.buildModelFromUrdf(str(urdf))
        self.data = self.model.createData()
        self.frames = {
            frame.name.removeprefix(strip): index
            for index, frame in enumerate(self.model.frames)
            if frame.type == pin.BODY
        }
        self.meshes = {}
        for link, triangles in link_triangles(urdf, strip).items():
            mesh = coal.BVHModelOBBRSS()
            mesh.beginModel(len(triangles), 3 * len(triangles))
            mesh.addVertices(triangles.reshape(-1, 3))
            mesh.addTriangles(np.arange(3 * len(triangles)).reshape(-1, 3))
            mesh.endModel()
            self.meshes[link] = mesh

    def pose(self, values: dict[str, float]) -> dict[str, coal.Transform3s]:
        """Every meshed link's placement at these joint values (by name; the others at zero)."""
        pin.framesForwardKinematics(self.model, self.data, configuration(self.model, values))
        return {
            link: coal.Transform3s(
                self.data.oMf[self.frames[link]].rotation, self.data.oMf[self.frames[link]].translation
            )
            for link in self.meshes
        }

    def distance(self, placed: dict[str, coal.Transform3s], first: str, second: str) -> float:
        """The gap between two posed links' meshes; 0 when they touch or cross."""
        a, b = self.meshes[first], self.meshes[second]
        crossing = coal.CollisionResult()
        if coal.collide(a, placed[first], b, placed[second], coal.CollisionRequest(), crossing):
            return 0.0
        return max(
            coal.distance(a, placed[first], b, placed[second], coal.DistanceRequest(), coal.DistanceResult()), 0.0
        )
