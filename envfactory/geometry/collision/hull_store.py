"""Convex hulls of collision meshes already built, kept on disk between processes.

Reading a mesh and building its hull (qhull) is most of what a robot with mesh collision shapes adds to a first
gym.make in a fresh process: about 0.1 s for the UR5e with its gripper. A hull is the same every time for the same
file and scale, so it is stored in coal's own binary serialization (every point, face and neighbour: a stored hull
measures exactly as a built one) under a key of the mesh's bytes, the scale, this module's and the mesh reader's
code, and coal's version. The safety proof measures with these hulls, so an entry carries the SHA-256 of its
serialization after it (coal's reader stops where the hull ends) and one that does not match is built again: a
damaged file is never measured with. ENVFACTORY_CACHE_DIR moves the store, =off switches it off.
"""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path

import coal
import numpy as np

from envfactory.geometry.collision import meshes
from envfactory.user_folders import cache_dir, store_in_cache

DIGEST_SIZE = hashlib.sha256().digest_size


def mesh_hull(mesh_file: Path, scale: np.ndarray) -> coal.ConvexBase:
    """The convex hull coal measures for this mesh file at this scale: stored, or built (and then stored)."""
    cache = cache_dir()
    if cache is None:
        return _built(mesh_file, scale)
    entry = cache / "hulls" / f"{_key(mesh_file, scale)}.coal"
    stored = _stored(entry)
    if stored is not None:
        return stored
    built = _built(mesh_file, scale)
    store_in_cache(entry.parent, entry.name, lambda path: _write(built, path))
    return built


def _built(mesh_file: Path, scale: np.ndarray) -> coal.ConvexBase:
    vertices, triangles = meshes.read_mesh(mesh_file)
    return meshes.hull(vertices * scale, triangles)


def _stored(entry: Path) -> coal.ConvexBase | None:
    """The hull an entry holds, or None when there is none or its digest does not match (built and stored again)."""
    try:
        data = entry.read_bytes()
    except OSError:
        return None
    serialized, digest = data[:-DIGEST_SIZE], data[-DIGEST_SIZE:]
    if len(data) <= DIGEST_SIZE or hashlib.sha256(serialized).digest() != digest:
        return None
    stored = coal.Convex()
    try:
        stored.loadFromBinary(str(entry))
    except (ValueError, RuntimeError):  # written by a coal whose format this one cannot read
        return None
    return stored


def _write(built: coal.ConvexBase, path: Path) -> None:
    try:
        built.saveToBinary(str(path))
    except ValueError as error:  # coal's word for a file it cannot open
        raise OSError(str(error)) from error
    serialized = path.read_bytes()
    with open(path, "ab") as entry:
        entry.write(hashlib.sha256(serialized).digest())


def _key(mesh_file: Path, scale: np.ndarray) -> str:
    digest = hashlib.sha256(_code_digest())
    digest.update(Path(mesh_file).read_bytes())
    digest.update(np.asarray(scale, dtype=float).tobytes())
    return digest.hexdigest()[:32]


@functools.cache
def _code_digest() -> bytes:
    """What every key shares: the code that reads and stores a hull, and coal's version (read once a process)."""
    digest = hashlib.sha256(coal.__version__.encode())
    for module in (__file__, meshes.__file__):
        digest.update(Path(module).read_bytes())
    return digest.digest()
