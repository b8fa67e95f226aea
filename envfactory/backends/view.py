"""What people see of a simulated scene, the same on both engines: the rendered picture's size and view, and the
goal marker's colour (never part of an observation: image terms use the scene's own camera)."""

from __future__ import annotations

from dataclasses import dataclass

RENDER_SIZE = (480, 360)  # width, height of render() and of the videos made from it
MARKER_RGBA = (0.1, 0.8, 0.2, 0.6)  # the goal marker: translucent green


@dataclass(frozen=True)
class RenderView:
    """An orbit camera on the table: it looks at a point `behind` m nearer the robot than the table's centre and
    `above` m over its top, from `distance` m away, `pitch` degrees down, turned `yaw` degrees (PyBullet's)
    about the vertical; MuJoCo's azimuth is `yaw` + 180."""

    behind: float = 0.15
    above: float = 0.1
    distance: float = 1.25
    yaw: float = 50.0
    pitch: float = -30.0

    def target(self, table) -> list[float]:
        return [table.center[0] - self.behind, table.center[1], table.top_z + self.above]


RENDER_VIEW = RenderView()
