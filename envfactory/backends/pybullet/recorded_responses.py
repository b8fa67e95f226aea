"""The gripper's recorded step response (fast_cycles.GripperResponse), kept on disk across processes.

Recording it opens a second PyBullet session and simulates the gripper across its range both ways: about 1,200
substeps, about a tenth of the first make of a gripper robot. The response depends only on what the recording is
made of, so it is kept beside the user config under a digest of all of it: the URDF as PyBullet loads it, the
size and time of every mesh file it names, the physics step and solver iterations, the gripper's range, force
and speed, and the versions of PyBullet and envfactory. Anything else, and it is recorded again.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from importlib.metadata import version
from pathlib import Path
from typing import Callable

from envfactory.backends.pybullet.fast_cycles import GripperResponse
from envfactory.registration import user_config
from envfactory.version import __version__

FOLDER = "gripper_responses"
_MESH_FILE = re.compile(r'filename="([^"]+)"')


def recording_digest(urdf_path: Path, settings: dict) -> str:
    """A digest of everything a recorded response depends on."""
    text = Path(urdf_path).read_text()
    meshes = []
    for name in sorted(set(_MESH_FILE.findall(text))):
        try:
            info = os.stat(name)
            meshes.append([name, info.st_size, info.st_mtime])
        except OSError:
            meshes.append([name, None, None])
    record = [text, meshes, settings, version("pybullet"), __version__]
    return hashlib.sha256(json.dumps(record, sort_keys=True).encode()).hexdigest()[:24]


def load_or_record(urdf_path: Path, settings: dict, record: Callable[[], GripperResponse]) -> GripperResponse:
    """The response kept for this digest, or `record()` kept for next time (a folder that cannot be written
    only costs the recording again)."""
    path = user_config.config_dir() / FOLDER / f"{recording_digest(urdf_path, settings)}.json"
    try:
        kept = json.loads(path.read_text())
        return GripperResponse(kept["closing"], kept["opening"], kept["dt"])
    except (OSError, ValueError, KeyError, TypeError):
        pass
    response = record()
    closing, opening = response.curves()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        partial = path.with_suffix(f".{os.getpid()}.tmp")
        partial.write_text(json.dumps({"closing": closing, "opening": opening, "dt": response.dt}))
        partial.replace(path)  # whole or not at all, for processes reading it meanwhile
    except OSError:
        pass
    return response
