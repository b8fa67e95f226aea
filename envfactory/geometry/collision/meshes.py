"""Collision meshes read here rather than through Pinocchio's mesh loader.

Pinocchio loads URDF meshes with assimp, whose first load in a process costs about 37 MB of memory however small
the meshes are (the UR5e's and the Robotiq's collision OBJs hold 7,000
vertices). The check measures a mesh as its convex hull, which only needs the vertices the faces use, so OBJ and
STL are read here: the URDF is handed to Pinocchio with each such mesh stood in for by a small sphere at the same
origin (so every shape keeps its name, index and placement), and the sphere is then replaced by the mesh's hull.
A URDF with any other mesh format goes to Pinocchio whole, as before.
"""

from __future__ import annotations

import struct
import xml.etree.ElementTree as ET
from pathlib import Path

import coal
import numpy as np

READABLE = (".obj", ".stl")
PLACEHOLDER_RADIUS = "0.001"


def read_mesh(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, triangles) of an OBJ or STL file, with only the vertices some face uses."""
    suffix = path.suffix.lower()
    if suffix == ".obj":
        vertices, triangles = _read_obj(path)
    elif suffix == ".stl":
        vertices, triangles = _read_stl(path)
    else:
        raise ValueError(f"{path}: no reader for {suffix} meshes here (OBJ and STL are read)")
    used = np.unique(triangles)
    renumber = np.full(len(vertices), -1, dtype=np.int64)
    renumber[used] = np.arange(len(used))
    return vertices[used], renumber[triangles]


def _read_obj(path: Path) -> tuple[np.ndarray, np.ndarray]:
    vertices, triangles = [], []
    for line in path.read_text(errors="replace").splitlines():
        if line.startswith("v "):
            vertices.append([float(value) for value in line.split()[1:4]])
        elif line.startswith("f "):
            # "f 1/2/3 4/5/6 ...": the vertex index before the first slash, 1-based or negative (from the end)
            corners = [int(token.split("/")[0]) for token in line.split()[1:]]
            corners = [c - 1 if c > 0 else len(vertices) + c for c in corners]
            triangles.extend([corners[0], corners[k], corners[k + 1]] for k in range(1, len(corners) - 1))
    # single precision, as assimp reads them: the hull's points, and so the pair list's digest, come out as they
    # did through Pinocchio's loader
    coordinates = np.array(vertices, dtype=np.float32).astype(float)
    return coordinates.reshape(-1, 3), np.array(triangles, dtype=np.int64).reshape(-1, 3)


def _read_stl(path: Path) -> tuple[np.ndarray, np.ndarray]:
    data = path.read_bytes()
    count = struct.unpack_from("<I", data, 80)[0] if len(data) >= 84 else -1
    if count >= 0 and len(data) == 84 + 50 * count:  # binary: a 50-byte record a triangle
        records = np.frombuffer(
            data,
            dtype=np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attr", "<u2")]),
            count=count,
            offset=84,
        )
        corners = records["corners"].astype(float).reshape(-1, 3)
    else:
        corners = (
            np.array(
                [
                    [float(v) for v in line.split()[1:4]]
                    for line in data.decode(errors="replace").splitlines()
                    if line.strip().startswith("vertex")
                ],
                dtype=np.float32,
            )
            .astype(float)
            .reshape(-1, 3)
        )
    return corners, np.arange(len(corners), dtype=np.int64).reshape(-1, 3)


def hull(vertices: np.ndarray, triangles: np.ndarray) -> coal.ConvexBase:
    """The convex hull coal measures, built as Pinocchio's meshes are (a BVH model, then its hull)."""
    model = coal.BVHModelOBBRSS()
    model.beginModel(len(triangles), len(vertices))
    model.addVertices(vertices)
    model.addTriangles(triangles)
    model.endModel()
    model.buildConvexHull(True, "Qt")
    return model.convex


def with_meshes_stood_in(urdf_path: Path) -> tuple[Path, dict[str, tuple[Path, np.ndarray]]]:
    """A copy of the URDF with each OBJ or STL collision mesh replaced by a small sphere at its origin, and for
    each the name Pinocchio gives that shape (`<link>_<index of the collision in the link>`) with the mesh file
    and its scale. The URDF itself, and no stand-ins, when a collision mesh has another format."""
    urdf_path = Path(urdf_path)
    root = ET.parse(urdf_path).getroot()
    stood_in: dict[str, tuple[Path, np.ndarray]] = {}
    for link in root.findall("link"):
        for index, collision in enumerate(link.findall("collision")):
            geometry = collision.find("geometry")
            mesh = geometry.find("mesh") if geometry is not None else None
            if mesh is None:
                continue
            path = Path(mesh.get("filename", ""))
            if not path.is_absolute() or path.suffix.lower() not in READABLE or not path.is_file():
                return urdf_path, {}
            scale = np.array([float(v) for v in mesh.get("scale", "1 1 1").split()], dtype=float)
            stood_in[f"{link.get('name')}_{index}"] = (path, scale)
            geometry.remove(mesh)
            ET.SubElement(geometry, "sphere", radius=PLACEHOLDER_RADIUS)
    if not stood_in:
        return urdf_path, {}
    copy = urdf_path.with_name(f"{urdf_path.stem}-meshes-stood-in.urdf")
    ET.ElementTree(root).write(copy, encoding="unicode")
    return copy, stood_in
