"""Convex hulls of collision meshes already built, kept on disk between processes.

Reading a mesh and building its hull (qhull) is most of what a robot with mesh collision shapes adds to a first
gym.make in a fresh process: about 0.1 s for the UR5e with its gripper. A hull is the same every time for the same
file and scale, so it is stored in coal's own serialization (every point, face and neighbour, so a stored hull
measures exactly as a built one) under a key of the mesh's bytes, the scale, this module's and the mesh reader's
code, and coal's version. ENVFACTORY_CACHE_DIR moves the store, =off switches it off.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import coal
import numpy as np

from envfactory.geometry.collision import meshes
from envfactory.user_folders import cache_dir, store_in_cache


def mesh_hull(mesh_file: Path, scale: np.ndarray) -> coal.ConvexBase:
    """The convex hull coal measures for this mesh file at this scale: stored, or built (and then stored)."""
    where = _folder()
    entry = f"{_key(mesh_file, scale)}.coal" if where is not None else ""
    if where is not None and (where / entry).is_file():
        stored = coal.Convex()
        try:
            stored.loadFromBinary(str(where / entry))
            return stored
        except (OSError, RuntimeError):  # unreadable (cut short, another coal's format): built and stored again
            pass
    vertices, triangles = meshes.read_mesh(mesh_file)
    built = meshes.hull(vertices * scale, triangles)
    if where is not None:
        store_in_cache(where, entry, lambda path: built.saveToBinary(str(path)))
    return built


def _folder() -> Path | None:
    cache = cache_dir()
    return None if cache is None else cache / "hulls"


def _key(mesh_file: Path, scale: np.ndarray) -> str:
    digest = hashlib.sha256()
    digest.update(Path(mesh_file).read_bytes())
    digest.update(np.asarray(scale, dtype=float).tobytes())
    digest.update(Path(__file__).read_bytes())
    digest.update(Path(meshes.__file__).read_bytes())
    digest.update(coal.__version__.encode())
    return digest.hexdigest()[:32]
