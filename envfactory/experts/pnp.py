"""Pick-and-place: open, come down over the cube, close, lift, carry, place.

A small phase machine; each phase checks the physics it relies on (the cube
between the fingers, the cube still held) and falls back to a fresh
approach when it is not so.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from envfactory.experts.motion import Expert
from envfactory.experts.points import APPROACH_WITHIN, PARAMS, ExpertPoint, approach_point, spawn_spots
from envfactory.terms.library import TermParams

# How near the EE must come to a point for the expert to go on; the compiler's reach checks allow the same
# slack (working_points).
GRASP_WITHIN = 0.006  # closes within this of the grasp point, m
LIFT_WITHIN = 0.01  # the carry height is reached within this, m


class CarryParams(TermParams):
    """How the gripper takes hold of a cube and carries it: one robot's geometry, whatever the task."""

    grasp_height: float = Field(default=0.0, ge=-0.5, le=0.5)  # EE height above the cube centre when closing, m
    clearance: float = Field(default=0.08, gt=0, le=1.0)  # EE height above the cube centre on the way in, m
    lift: float = Field(default=0.15, gt=0, le=2.0)  # carry height above the spawn point at least, m
    step: float = Field(default=0.04, gt=0, le=0.5)  # EE travel per action, m
    close_steps: int = Field(default=3, ge=1, le=100)  # actions spent closing before lifting
    # the gripper command that holds the object (default: fully closed). A value just past contact
    # keeps the commanded finger sweep, and so the room the safety check needs below it, short.
    grip: float | None = None

    def holding(self, gripper) -> float:
        """The gripper command that holds the object: `grip`, or fully closed."""
        return gripper.closed if self.grip is None else self.grip


class PickPlaceParams(CarryParams):
    object: str = "cube"


class PickPlaceExpert(Expert):
    Params = PickPlaceParams

    @classmethod
    def working_points(cls, params, spec) -> list[ExpertPoint]:
        """The grasp over every spawn spot, the lift straight up from the spawn, the place (the goal box's
        corners raised by grasp_height, the object then within the goal's tolerance) and the approach."""
        obj = spec.task.objects.get(params.object)
        if obj is None:
            return []
        gripper = spec.robot.gripper
        grip = params.holding(gripper) if gripper is not None else 0.0
        held = (gripper.open, grip) if gripper is not None else (0.0,)
        points = [
            ExpertPoint(
                "grasp",
                f"{PARAMS}.grasp_height",
                spawn_spots(obj) + [0, 0, params.grasp_height],
                params.grasp_height,
                held,
                GRASP_WITHIN,
            )
        ]
        goal = spec.task.goal
        if params.object in goal.parts:
            low, high = (np.asarray(b, float) + goal.part_offsets[goal.parts.index(params.object)] for b in goal.box)
            corners = np.array(
                [[x, y, z] for x in (low[0], high[0]) for y in (low[1], high[1]) for z in (low[2], high[2])]
            )
            lifted = np.array([np.asarray(obj.spawn.position, float) + [0, 0, params.grasp_height + params.lift]])
            points += [
                ExpertPoint(
                    "place",
                    "task.goal.box" if params.object == goal.parts[0] else f"task.goal.also.{params.object}.offset",
                    corners + [0, 0, params.grasp_height],
                    params.grasp_height,
                    (grip,),
                    goal.tolerance,
                ),
                ExpertPoint("lift", f"{PARAMS}.lift", lifted, params.grasp_height + params.lift, (grip,), LIFT_WITHIN),
            ]
        return points + [approach_point(params, obj)]

    @classmethod
    def check(cls, params, spec) -> list[tuple[str, str]]:
        gripper = spec.robot.gripper
        if params.grip is not None and gripper is not None and not gripper.low <= params.grip <= gripper.high:
            return [
                ("grip", f"grip {params.grip:g} lies outside the gripper's range [{gripper.low:g}, {gripper.high:g}]")
            ]
        return []

    def reset(self) -> None:
        self.phase = "approach"
        self.closing = 0
        self.hold_offset = np.zeros(3)  # cube centre relative to the EE once grasped
        self.floor_z = None

    def __call__(self, observation):
        env, p, motion = self.env, self.params, self.motion
        state = env.state
        cube_state = state.objects[p.object]
        cube, ee = cube_state.position, state.ee_position
        gripper = motion.gripper
        grip = p.holding(gripper)
        if self.floor_z is None:
            self.floor_z = cube[2]
        rotation = self.grasp_rotation(cube_state)
        above = np.append(cube[:2], cube[2] + p.clearance)
        grasp = np.append(cube[:2], cube[2] + p.grasp_height)

        # the cube slipped out when it is no longer as far from the EE as when it was grasped (a cube that only
        # turns in the grip keeps that distance): open, rise and start again
        held_at = np.linalg.norm(self.hold_offset)
        if self.phase in ("lift", "carry", "place") and abs(np.linalg.norm(cube - ee) - held_at) > 0.03:
            self.phase = "release"
        if self.phase == "release":
            if gripper.closure(state.gripper) < 0.1 and ee[2] > cube[2] + p.clearance - 0.02:
                self.phase = "approach"
            else:
                return motion.toward(np.append(ee[:2], cube[2] + p.clearance), gripper=gripper.open, max_step=p.step)
        if self.phase == "approach":
            if np.linalg.norm(ee[:2] - cube[:2]) < 0.008 and abs(ee[2] - above[2]) < APPROACH_WITHIN:
                self.phase = "descend"
            else:
                if ee[2] < above[2] - 0.03 and np.linalg.norm(ee[:2] - cube[:2]) > 0.02:
                    return motion.toward(np.append(ee[:2], above[2]), rotation, gripper.open, p.step)
                return motion.toward(above, rotation, gripper.open, p.step)
        if self.phase == "descend":
            if np.linalg.norm(ee[:2] - cube[:2]) > 0.015:
                self.phase = "approach"
                return motion.toward(above, rotation, gripper.open, p.step)
            if np.linalg.norm(ee - grasp) < GRASP_WITHIN:
                self.phase, self.closing = "close", 0
            else:
                return motion.toward(grasp, rotation, gripper.open, p.step / 2)
        if self.phase == "close":
            self.closing += 1
            if self.closing > p.close_steps:
                self.phase = "lift"
                self.hold_offset = cube - ee
                self.grasped()
            else:
                return motion.toward(grasp, rotation, grip, p.step / 2)
        goal = env.goal_of(p.object)
        ee_goal = goal - self.hold_offset
        carry_z = max(ee_goal[2], self.floor_z - self.hold_offset[2] + p.lift)
        if self.phase == "lift":
            # straight up first: the lift stage, and clear of the table
            if ee[2] < carry_z - LIFT_WITHIN:
                return motion.toward(np.append(ee[:2], carry_z), state.ee_rotation, grip, p.step)
            self.phase = "carry"
        if self.phase == "carry" and np.linalg.norm(ee[:2] - ee_goal[:2]) > 0.01:
            return motion.toward(np.append(ee_goal[:2], carry_z), self.held_rotation(), grip, p.step)
        self.phase = "place"
        return self.place(goal, grip)

    # ------------------------------------------------------------ what a variant of the task changes

    def grasp_rotation(self, cube_state):
        """The EE's orientation when it closes: square to the cube's faces."""
        return self.motion.square_to(float(cube_state.rpy[2]))

    def grasped(self) -> None:
        """The grip just closed on the cube."""

    def held_rotation(self):
        """The EE's orientation while it carries the cube: as it is."""
        return self.env.state.ee_rotation

    def place(self, goal: np.ndarray, grip: float):
        # closed on the cube itself: a cube that turns or slides in the grip moves its offset from the EE,
        # and holding the EE where that offset once put the cube would let the cube drift off the goal
        state = self.env.state
        cube = state.objects[self.params.object].position
        return self.motion.toward(state.ee_position + (goal - cube), self.held_rotation(), grip, self.params.step)
