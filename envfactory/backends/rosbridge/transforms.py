"""Frames of object poses: from the camera's frame to the task frame, through declared
static transforms and, when enabled, what /tf and /tf_static announce."""

from __future__ import annotations

import threading

import numpy as np
import pinocchio as pin

from envfactory.geometry.kinematics import quaternion_to_matrix
from envfactory.schema.models import StaticTransform


class FrameGraph:
    MAX_HOPS = 8

    def __init__(self, task_frame: str, static: dict[str, StaticTransform]):
        self.task_frame = task_frame
        self._lock = threading.Lock()
        # child -> (parent, rotation, translation): the child's pose in its parent
        self._edges: dict[str, tuple[str, np.ndarray, np.ndarray]] = {
            child: (t.parent, pin.rpy.rpyToMatrix(*t.rpy), np.asarray(t.xyz, float)) for child, t in static.items()
        }

    def learn(self, tf_message: dict) -> None:
        """Take in a tf2_msgs/TFMessage."""
        for item in tf_message.get("transforms", []):
            try:
                t, r = item["transform"]["translation"], item["transform"]["rotation"]
                rotation = quaternion_to_matrix([r["x"], r["y"], r["z"], r["w"]])
                edge = (item["header"]["frame_id"].lstrip("/"), rotation, np.array([t["x"], t["y"], t["z"]], float))
                with self._lock:
                    self._edges[item["child_frame_id"].lstrip("/")] = edge
            except (KeyError, TypeError, ValueError):
                continue  # a broken transform teaches nothing; the pose lookup then fails with a reason

    def to_task(self, frame: str, position: np.ndarray, quaternion: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The pose in the task frame; KeyError names the frame with no way there."""
        frame = frame.lstrip("/") or self.task_frame
        rotation, translation = quaternion_to_matrix(quaternion), np.asarray(position, float)
        hops = 0
        with self._lock:
            while frame != self.task_frame:
                if frame not in self._edges or hops == self.MAX_HOPS:
                    raise KeyError(f"no transform from frame {frame!r} to the task frame {self.task_frame!r}")
                parent, parent_rotation, parent_translation = self._edges[frame]
                rotation, translation = parent_rotation @ rotation, parent_rotation @ translation + parent_translation
                frame, hops = parent, hops + 1
        quaternion = pin.Quaternion(rotation).coeffs()  # x, y, z, w
        return translation, np.asarray(quaternion, float)
