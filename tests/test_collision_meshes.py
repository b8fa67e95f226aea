"""Collision meshes read without assimp (geometry/collision/meshes.py), judged by assimp: coal's own mesh loader
must find the same convex hull in every shipped collision mesh and in STL files of both encodings; and the store that
keeps the hulls between processes (hull_store.py) serves exactly what it was given, or builds again."""

from __future__ import annotations

import struct
from pathlib import Path

import coal
import numpy as np
import pytest

from envfactory import factory
from envfactory.geometry.collision import hull_store, meshes
from envfactory.geometry.collision.meshes import hull, read_mesh, with_meshes_stood_in
from envfactory.geometry.collision.model import CollisionModel
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


def _write_stl(path: Path, binary: bool, corners: np.ndarray = CUBE) -> None:
    if binary:
        records = b"".join(
            struct.pack("<3f", 0, 0, 0) + b"".join(struct.pack("<3f", *corners[i]) for i in face) + b"\0\0"
            for face in CUBE_FACES
        )
        path.write_bytes(b"\0" * 80 + struct.pack("<I", len(CUBE_FACES)) + records)
    else:
        lines = ["solid cube"]
        for face in CUBE_FACES:
            lines += ["facet normal 0 0 0", "outer loop"]
            lines += [f"vertex {x:.6f} {y:.6f} {z:.6f}" for x, y, z in corners[list(face)]]
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


def _distances_to_boxes(geometry, count: int = 200) -> np.ndarray:
    """coal's distance from the shape to a box at random places around it (translation only)."""
    rng = np.random.default_rng(0)
    box, request = coal.Box(0.05, 0.08, 0.12), coal.DistanceRequest()
    return np.array(
        [
            coal.distance(
                geometry,
                coal.Transform3s(),
                box,
                coal.Transform3s(np.eye(3), rng.uniform(-0.3, 0.3, 3)),
                request,
                coal.DistanceResult(),
            )
            for _ in range(count)
        ]
    )


def test_a_stored_hull_measures_exactly_as_a_built_one(tmp_path, monkeypatch):
    monkeypatch.setenv("ENVFACTORY_CACHE_DIR", str(tmp_path))
    path, scale = max(_shipped_meshes(), key=lambda mesh: mesh[0].stat().st_size)
    vertices, triangles = read_mesh(path)
    built = hull(vertices * scale, triangles)
    hull_store.mesh_hull(path, scale)  # builds and stores
    assert len(list((tmp_path / "hulls").glob("*.coal"))) == 1
    stored = hull_store.mesh_hull(path, scale)
    assert stored.num_points == built.num_points and stored.num_polygons == built.num_polygons
    assert np.array_equal(np.asarray(shape_points(stored)), np.asarray(shape_points(built)))
    assert np.array_equal(_distances_to_boxes(stored), _distances_to_boxes(built))


def _stored_cube(tmp_path, monkeypatch) -> tuple[Path, Path]:
    """A cube mesh, its hull built and stored: (mesh, the store's entry)."""
    monkeypatch.setenv("ENVFACTORY_CACHE_DIR", str(tmp_path))
    mesh = tmp_path / "cube.stl"
    _write_stl(mesh, binary=True)
    hull_store.mesh_hull(mesh, np.ones(3))
    (entry,) = (tmp_path / "hulls").glob("*.coal")
    return mesh, entry


def test_a_stored_hull_cut_short_is_built_again(tmp_path, monkeypatch):
    mesh, entry = _stored_cube(tmp_path, monkeypatch)
    entry.write_bytes(entry.read_bytes()[:40])
    again = hull_store.mesh_hull(mesh, np.ones(3))
    assert np.array_equal(_sorted_points(again), _sorted_points(hull(*read_mesh(mesh))))
    reread = coal.Convex()
    reread.loadFromBinary(str(entry))  # stored again, whole
    assert reread.num_points == 8


def test_a_damaged_stored_hull_is_never_measured_with(tmp_path, monkeypatch):
    mesh, entry = _stored_cube(tmp_path, monkeypatch)
    data = bytearray(entry.read_bytes())
    # a corner's coordinate (a double, 0.05 in the file) grown to 0.5: coal itself reads the file without a word
    where = data.rfind(np.float64(np.float32(0.05)).tobytes())
    data[where : where + 8] = np.float64(0.5).tobytes()
    entry.write_bytes(bytes(data))
    damaged = coal.Convex()
    damaged.loadFromBinary(str(entry))
    assert _sorted_points(damaged).max() == pytest.approx(0.5)
    served = hull_store.mesh_hull(mesh, np.ones(3))
    assert np.allclose(_sorted_points(served).max(axis=0), [0.02, 0.03, 0.05])


def test_an_edited_mesh_or_another_scale_is_not_served_the_stored_hull(tmp_path, monkeypatch):
    monkeypatch.setenv("ENVFACTORY_CACHE_DIR", str(tmp_path))
    mesh = tmp_path / "cube.stl"
    _write_stl(mesh, binary=True)
    first = _sorted_points(hull_store.mesh_hull(mesh, np.ones(3)))
    assert np.allclose(first.max(axis=0), [0.02, 0.03, 0.05])
    assert np.allclose(
        _sorted_points(hull_store.mesh_hull(mesh, np.array([2.0, 1.0, 1.0]))).max(axis=0), [0.04, 0.03, 0.05]
    )
    _write_stl(mesh, binary=True, corners=CUBE * 3)
    assert np.allclose(_sorted_points(hull_store.mesh_hull(mesh, np.ones(3))).max(axis=0), [0.06, 0.09, 0.15])
    assert len(list((tmp_path / "hulls").glob("*.coal"))) == 3


def test_with_the_cache_off_nothing_is_stored(tmp_path, monkeypatch):
    monkeypatch.setenv("ENVFACTORY_CACHE_DIR", "off")
    mesh = tmp_path / "cube.stl"
    _write_stl(mesh, binary=False)
    assert _sorted_points(hull_store.mesh_hull(mesh, np.ones(3))).shape == (8, 3)
    assert sorted(path.name for path in tmp_path.iterdir()) == ["cube.stl"]


def test_a_later_collision_model_is_served_every_mesh_hull_from_the_store(tmp_path, monkeypatch):
    monkeypatch.setenv("ENVFACTORY_CACHE_DIR", str(tmp_path))
    blueprint = factory.blueprint("UR5ePushSim-v0")
    kinematics = robot_chain(blueprint.spec, blueprint.asset_root)[1]
    first = CollisionModel(kinematics.measuring_copy(), [])

    def no_qhull(*args):
        raise AssertionError("a hull was built although the store holds it")

    monkeypatch.setattr(meshes, "hull", no_qhull)
    later = CollisionModel(kinematics.measuring_copy(), [])
    pairs = zip(first.geometry.geometryObjects, later.geometry.geometryObjects, strict=True)
    meshed = [(a, b) for a, b in pairs if isinstance(a.geometry, coal.ConvexBase)]
    assert len(meshed) >= 10
    for a, b in meshed:
        assert np.array_equal(_sorted_points(a.geometry), _sorted_points(b.geometry)), a.name
