"""Where a scripted expert must put the EE: each expert names its own working points (grasp, push, approach,
place, lift) from its params and the task's spawn and goal boxes, in the task frame.

The compiler's checks of the workspace and of reach and safety judge these points, so an expert that could
never reach its grasp is refused before a single episode runs at 0%.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

PARAMS = "task.expert.params"
APPROACH_WITHIN = 0.03  # the approach height counts as reached within this, m


@dataclass(frozen=True)
class ExpertPoint:
    name: str  # what the expert does there: "grasp", "push", ...
    param: str  # the dotted path of the param that sets its height
    points: np.ndarray  # (n, 3) task-frame EE positions: the point at the spawn centre first, then its corners
    offset: float  # the EE's height above the object's centre there
    gripper: tuple[float, ...]  # the gripper values the expert holds there
    # how near the EE must come for the expert to go on (the experts' own thresholds): an
    # EE held this far off by the workspace still does the job
    slack: float
    direction: np.ndarray | None = None  # the push direction (x, y) of a push point
    # the EE orientations the expert may hold there, any one of which will do (None: the gripper pointing down,
    # squared to the object or laid across the push)
    rotations: tuple[np.ndarray, ...] | None = None


def spawn_spots(obj) -> np.ndarray:
    """The object's spawn centre, then the corners of its random spawn offset (z unchanged)."""
    spawn = np.asarray(obj.spawn.position, float)
    offset = np.array([*obj.spawn.offset, 0.0]) if obj.spawn.random else np.zeros(3)
    return np.array([spawn] + [spawn + offset * [sx, sy, 0.0] for sx in (-1, 1) for sy in (-1, 1)])


def approach_point(params, obj) -> ExpertPoint:
    """Above the object by the expert's clearance, on the way in."""
    return ExpertPoint(
        "approach",
        f"{PARAMS}.clearance",
        spawn_spots(obj) + [0, 0, params.clearance],
        params.clearance,
        (),
        APPROACH_WITHIN,
    )
