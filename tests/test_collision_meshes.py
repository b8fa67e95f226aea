"""Collision meshes read without assimp (geometry/collision/meshes.py), judged by assimp: coal's own mesh loader
must find the same convex hull in every shipped collision mesh and in STL files of both encodings."""

from __future__ import annotations

import struct
from pathlib import Path

import coal
import numpy as np
import pytest

from envfactory import factory
from envfactory.geometry.collision.meshes import hull, read_mesh, with_meshes_stood_in
from envfactory.geometry.collision.shapes import shape_points
from envfactory.geometry.robot_model import robot_chain


def _sorted_points(geometry) -> np.ndarray:
    points = np.asarray(shape_points(geometry), float)
    return points[np.lexsort(points.T[::-1])]


def _assimp_hull(path: Path, scale: np.ndarray):
    mesh = coal.MeshLoader().load(str(path), scale)
    mesh.buildConvexHull(True, "Qt")
    return mesh.convex


def _shipped_meshes() -> list[tuple[Path, np.ndarray]]:
    blueprint = factory.blueprint("UR5ePushSim-v0")
    urdf = robot_chain(blueprint.spec, blueprint.asset_root)[0]
    return list(with_meshes_stood_in(urdf)[1].values())


def test_every_shipped_collision_mesh_has_the_hull_assimp_finds():
    meshes = _shipped_meshes()
    assert len(meshes) >= 10, "the UR5e and its gripper have mesh collision shapes: none were stood in"
    for path, scale in meshes:
        vertices, triangles = read_mesh(path)
        ours, theirs = _sorted_points(hull(vertices * scale, triangles)), _sorted_points(_assimp_hull(path, scale))
        assert ours.shape == theirs.shape, path
        # assimp parses in single precision with a rounding of its own: the same points to a few nanometres
        assert np.abs(ours - theirs).max() < 1e-8, path


CUBE = np.array([[x, y, z] for x in (0.0, 0.02) for y in (0.0, 0.03) for z in (0.0, 0.05)])
CUBE_FACES = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1), (2, 3, 7), (2, 7, 6)]
CUBE_FACES += [(0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]


def _write_stl(path: Path, binary: bool) -> None:
    if binary:
        records = b"".join(
            struct.pack("<3f", 0, 0, 0) + b"".join(struct.pack("<3f", *CUBE[i]) for i in face) + b"\0\0"
            for face in CUBE_FACES
        )
        path.write_bytes(b"\0" * 80 + struct.pack("<I", len(CUBE_FACES)) + records)
    else:
        lines = ["solid cube"]
        for face in CUBE_FACES:
            lines += ["facet normal 0 0 0", "outer loop"]
            lines += [f"vertex {x:.6f} {y:.6f} {z:.6f}" for x, y, z in CUBE[list(face)]]
            lines += ["endloop", "endfacet"]
        path.write_text("\n".join(lines + ["endsolid cube"]) + "\n")


@pytest.mark.parametrize("binary", [True, False], ids=["binary", "ascii"])
def test_an_stl_mesh_has_the_hull_assimp_finds(tmp_path, binary):
    path = tmp_path / "cube.stl"
    _write_stl(path, binary)
    vertices, triangles = read_mesh(path)
    scale = np.array([2.0, 1.0, 0.5])
    ours, theirs = _sorted_points(hull(vertices * scale, triangles)), _sorted_points(_assimp_hull(path, scale))
    assert ours.shape == theirs.shape == (8, 3)
    assert np.abs(ours - theirs).max() < 1e-8


def test_a_mesh_format_not_read_here_leaves_the_urdf_to_pinocchio(tmp_path):
    mesh = tmp_path / "part.dae"
    mesh.write_text("<COLLADA/>")
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(
        f'<robot name="arm"><link name="a"><collision><geometry><mesh filename="{mesh}"/></geometry></collision>'
        "</link></robot>"
    )
    assert with_meshes_stood_in(urdf) == (urdf, {})
