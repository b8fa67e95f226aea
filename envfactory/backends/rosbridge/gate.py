"""The motion gate: a real arm moves only when the user said so, by kwarg, environment variable or CLI flag;
asked at construction and again before every command is published."""

from __future__ import annotations

import os

from envfactory.backends.base import MotionRefused

MOTION_ENV_VAR = "ALLOW_REAL_ROBOT_MOTION"


def motion_allowed(flag: bool) -> bool:
    return flag or os.environ.get(MOTION_ENV_VAR, "") == "1"


def require_motion_gate(flag: bool, what: str) -> None:
    if not motion_allowed(flag):
        raise MotionRefused(
            f"{what}: real-robot motion is not allowed. Pass allow_real_robot_motion=True, set "
            f"{MOTION_ENV_VAR}=1, or use the CLI's --allow-real-robot-motion once the workspace is clear."
        )
