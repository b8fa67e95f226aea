"""Image observation terms from the scene camera (use_kinect): each is a key of the Dict observation."""

from __future__ import annotations

import numpy as np

from envfactory.terms.library import image_term


@image_term(
    shape=lambda camera: (camera.height, camera.width, 3),
    dtype=np.uint8,
    bounds=lambda camera: (0, 255),
    description="RGB image, uint8",
)
def rgb(frame):
    return frame.rgb


@image_term(
    shape=lambda camera: (camera.height, camera.width),
    dtype=np.float32,
    bounds=lambda camera: (0.0, camera.far),
    description="depth along the view axis, m",
)
def depth(frame):
    return frame.depth
