"""Drawer: come down over the handle with the fingers open along the drawer's travel, one on each side of the bar,
close, pull along the travel to the goal, let go, rise.

The fingers close along the travel, so the pull presses the bar against the finger between it and the drawer's
face rather than asking the grip's friction to hold it (fingers closed along the bar let it slip out at the
first pull: measured on the UR5e, 8 mm of opening before the bar left the pads).
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from envfactory.experts.motion import Expert
from envfactory.experts.points import APPROACH_WITHIN, PARAMS, ExpertPoint
from envfactory.terms.library import TermParams

GRASP_WITHIN = 0.006  # closes within this of the grasp point, m
SLIPPED = 0.03  # the handle moved this far from where the hand holds it: the grip is lost, m
GRIPPER_STILL = 0.01  # the gripper moved less than this over an action: it stopped on the bar (its joint units)


class DrawerParams(TermParams):
    object: str = "cabinet"  # the fixture whose joint the goal opens
    grasp_height: float = Field(default=0.0, ge=-0.5, le=0.5)  # EE height above the handle's centre when closing, m
    clearance: float = Field(default=0.08, gt=0, le=1.0)  # EE height above the handle's centre on the way in, m
    step: float = Field(default=0.03, gt=0, le=0.5)  # EE travel per action, m
    close_steps: int = Field(default=8, ge=1, le=100)  # most actions spent closing before pulling
    grip: float | None = None  # the gripper command that holds the handle (default: fully closed)
    # the gripper value on the way in (default: fully open): open no wider than the gap behind the bar needs, so
    # that the finger going in there keeps the safety margin from the drawer's face
    opening: float | None = None


class DrawerExpert(Expert):
    Params = DrawerParams

    @classmethod
    def working_points(cls, params, spec) -> list[ExpertPoint]:
        """The grasp held where the goal box puts the handle (the hand pulls it there), with the fingers along
        the drawer's travel, and the approach above it."""
        goal, gripper = spec.task.goal, spec.robot.gripper
        if params.object not in spec.task.fixtures or goal.parts[0] != params.object or gripper is None:
            return []
        low, high = (np.asarray(b, float) for b in goal.box)
        ends = np.array([low, high])
        # the goal box runs along the drawer's travel: the way the fingers close
        along = high[:2] - low[:2]
        along = along if np.linalg.norm(along) > 0 else np.array([1.0, 0.0])
        grip = gripper.closed if params.grip is None else params.grip
        opening = gripper.open if params.opening is None else params.opening
        return [
            ExpertPoint(
                "grasp",
                f"{PARAMS}.grasp_height",
                ends + [0, 0, params.grasp_height],
                params.grasp_height,
                (opening, grip),
                goal.tolerance,
                direction=along,
            ),
            ExpertPoint("approach", f"{PARAMS}.clearance", ends + [0, 0, params.clearance], params.clearance, (), 0.03),
        ]

    def reset(self) -> None:
        self.phase = "approach"
        self.closing = 0
        self.hold_offset = np.zeros(3)  # the handle relative to the EE once closed on it
        fixture = self.env.fixtures[self.params.object]
        self.travel = (self.env.task_frame.rotation.T @ fixture.travel)[:2]

    def __call__(self, observation):
        env, p, motion = self.env, self.params, self.motion
        state = env.state
        handle, ee = state.objects[p.object].position, state.ee_position
        gripper = motion.gripper
        grip = gripper.closed if p.grip is None else p.grip
        opening = gripper.open if p.opening is None else p.opening
        rotation = motion.down_facing(self.travel)
        above = handle + [0, 0, p.clearance]
        grasp = handle + [0, 0, p.grasp_height]
        goal = env.goal_of(p.object)

        holding = self.phase in ("pull", "let go")
        if holding and abs(np.linalg.norm(handle - ee) - np.linalg.norm(self.hold_offset)) > SLIPPED:
            self.phase = "release"
        if self.phase == "release":
            if gripper.closure(state.gripper) <= gripper.closure(opening) + 0.1 and ee[2] > above[2] - 0.02:
                self.phase = "approach"
            else:
                return motion.toward(np.append(ee[:2], above[2]), gripper=opening, max_step=p.step)
        if self.phase == "approach":
            if np.linalg.norm(ee[:2] - handle[:2]) < 0.008 and abs(ee[2] - above[2]) < APPROACH_WITHIN:
                self.phase = "descend"
            else:
                if ee[2] < above[2] - 0.03 and np.linalg.norm(ee[:2] - handle[:2]) > 0.02:
                    return motion.toward(np.append(ee[:2], above[2]), rotation, opening, p.step)
                return motion.toward(above, rotation, opening, p.step)
        if self.phase == "descend":
            if np.linalg.norm(ee[:2] - handle[:2]) > 0.015:
                self.phase = "approach"
                return motion.toward(above, rotation, opening, p.step)
            if np.linalg.norm(ee - grasp) < GRASP_WITHIN:
                self.phase, self.closing, self.last_gripper = "close", 0, state.gripper
            else:
                return motion.toward(grasp, rotation, opening, p.step / 2)
        if self.phase == "close":
            # closing until the fingers stop on the bar (or reach the grip): a pull before then leaves it behind
            self.closing += 1
            moving = (
                abs(state.gripper - self.last_gripper) > GRIPPER_STILL and abs(state.gripper - grip) > GRIPPER_STILL
            )
            self.last_gripper = state.gripper
            if self.closing <= 1 or (moving and self.closing <= p.close_steps):
                return motion.toward(grasp, rotation, grip, p.step / 2)
            self.phase, self.hold_offset = "pull", handle - ee
        if self.phase == "pull":
            if np.linalg.norm(goal - handle) > 0.3 * env.blueprint.spec.task.goal.tolerance:
                # the hand moves the handle by what is left to go: a drawer that lags the hand is pulled on
                return motion.toward(ee + (goal - handle), rotation, grip, p.step)
            self.phase = "let go"
        if self.phase == "let go":
            if gripper.closure(state.gripper) > gripper.closure(opening) + 0.1:
                return motion.toward(ee, rotation, opening, p.step)
            self.phase = "rise"
        return motion.toward(np.append(ee[:2], above[2]), rotation, opening, p.step)
