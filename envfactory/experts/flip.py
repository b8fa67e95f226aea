"""Flip: pick the cube, lift it a little, turn the hand by the goal's turn, carry the cube over the goal and let
it go a few centimetres above the table, so that it lands on its new face.

The turn the cube needs is R_goal R_cube^T (task frame). The fingers close on the two faces the turn's axis
passes through, and the hand turns about that axis: the pads' grip turns the cube with it (measured: within
0.05 rad of the hand). Closed across the axis instead, a finger would end under the cube, and the hand turned
on its side would stand as tall as it is wide (20 cm on the Panda). Along the axis it stands as tall as it is
thick, but its wrist still keeps it above the table: it lets go at `drop` above the cube's resting height.

The fingers along the axis leave the hand two ways round; turned, each asks another arm pose. The expert takes
the first whose pose, where the hand turns and over the goal, the arm holds clear of the table and itself
(IK and the safety check), and `validate` asks the same of the goal box's centre for each turn the goal may
draw (working points with `rotations`).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from pydantic import Field

from envfactory.experts.pnp import PickPlaceExpert, PickPlaceParams
from envfactory.experts.points import ExpertPoint
from envfactory.geometry.frames import nearest_top_down
from envfactory.geometry.kinematics import quaternion_to_matrix
from envfactory.schema.task import TURN_AXES

TURNED_WITHIN = 0.05  # rad: the hand's turn counts as done within this
OVER_GOAL_WITHIN = 0.01  # m: the cube is let go within this of the point above its goal


class FlipParams(PickPlaceParams):
    drop: float = Field(default=0.03, ge=0, le=0.2)  # m above its resting height at which the cube is let go


class FlipExpert(PickPlaceExpert):
    Params = FlipParams

    @classmethod
    def working_points(cls, params, spec) -> list[ExpertPoint]:
        """Pick-and-Place's points, and for each turn the goal may ask, the hand holding the cube turned over the
        goal box's centre, where it lets go: either way round (the expert takes the one the arm can hold)."""
        points = super().working_points(params, spec)
        turn = spec.task.goal.orientation.get(params.object)
        robot = spec.robot
        if turn is None or robot.top_down_rpy is None or robot.gripper is None:
            return points
        down = pin.rpy.rpyToMatrix(*robot.top_down_rpy)
        closing = "xyz".index(robot.gripper.closing_axis)
        grip = params.holding(robot.gripper)
        centre = np.mean(np.asarray(spec.task.goal.box, float), axis=0) + [0.0, 0.0, params.drop]
        for axis in turn.axes:
            direction = np.asarray(TURN_AXES[axis])
            rotation = pin.exp3(direction * np.radians(turn.angle))
            if np.linalg.norm(direction[:2]) < 1e-9:
                continue  # a turn about the vertical is a turn of the wrist: the grasp and place points hold it
            one = nearest_top_down(down, down, closing, float(np.arctan2(direction[1], direction[0])), np.pi)
            grasps = (one, pin.rpy.rpyToMatrix(0.0, 0.0, np.pi) @ one)
            held = centre - rotation @ np.array([0.0, 0.0, -params.grasp_height])  # the EE, the cube turned under it
            points.append(
                ExpertPoint(
                    f"turn about {axis}",
                    f"task.goal.orientation.{params.object}.axes",
                    held[None, :],
                    params.drop,
                    (grip,),
                    OVER_GOAL_WITHIN,
                    rotations=tuple(rotation @ grasp for grasp in grasps),
                )
            )
        return points

    def reset(self) -> None:
        super().reset()
        self.turn = None  # R_goal R_cube^T, read at the first step (the goal is drawn at reset)
        self.target = None  # the EE's orientation that holds the cube turned
        self.releasing = False
        self.lifted_at = None  # where the lift ended: the hand turns there
        self.turned_once = False  # the turn is done: the carry goes on, still turning within its tolerance
        self.grip_choice = None  # the grasp orientation, chosen once the goal is known

    def _turn(self) -> np.ndarray:
        if self.turn is None:
            state, p = self.env.state, self.params
            goal = quaternion_to_matrix(self.env.goal_parts.orientation(self.env.goal, p.object))
            self.turn = goal @ state.objects[p.object].rotation.T
        return self.turn

    def grasp_rotation(self, cube_state):
        axis = pin.log3(self._turn())
        if np.linalg.norm(axis[:2]) <= abs(axis[2]):  # a turn about the vertical: any square grip turns it
            return super().grasp_rotation(cube_state)
        if self.grip_choice is None:
            # the fingers along the axis, the hand either way round: the same grip, but turned, the two
            # hands hold different arm poses over the goal; the first the arm can hold clear of the table
            one = self.motion.down_facing(axis[:2])
            other = pin.rpy.rpyToMatrix(0.0, 0.0, np.pi) @ one
            self.grip_choice = next((r for r in (one, other) if self._holds_turned(r)), one)
        return self.grip_choice

    def _holds_turned(self, grasp: np.ndarray) -> bool:
        """Whether the arm can hold the cube turned where the hand turns (above the cube, at the lift height) and
        where it lets go (over the goal)."""
        env, p = self.env, self.params
        state = env.state
        turned = self._turn() @ grasp
        cube_from_ee = self._turn() @ np.array([0.0, 0.0, -p.grasp_height])
        cube = state.objects[p.object].position
        lifted = cube + [0.0, 0.0, p.lift]
        over = env.goal_of(p.object) + [0.0, 0.0, p.drop]
        grip = p.holding(self.motion.gripper)
        q = state.q_arm
        for point in (lifted, over):
            solution = env.kinematics.solve_ik(
                q, point - cube_from_ee, target_rotation=turned, gripper=grip, rotation_weight=1.0
            )
            if not (solution.success and env.safety.pose_is_clear(solution.q_arm, grip)):
                return False
            q = solution.q_arm
        return True

    def grasped(self) -> None:
        self.target = self._turn() @ self.env.state.ee_rotation

    def held_rotation(self):
        return self.target if self.target is not None else self.env.state.ee_rotation

    def __call__(self, observation):
        if self.releasing:  # the cube is let go: nothing of the pick-and-place's grip checks applies
            return self._release()
        if self.phase == "carry" and self.lifted_at is None:
            self.lifted_at = self.env.state.ee_position.copy()
        if self.phase == "carry" and not self.turned_once:
            self.turned_once = self._turned()
        if self.phase == "carry" and not self.turned_once:
            # the turn first, where the lift ended, clear of the table: turning on the way down trades height
            # for orientation wherever the arm cannot give both
            return self.motion.toward(
                self.lifted_at,
                self.target,
                self.params.holding(self.motion.gripper),
                self.params.step,
            )
        return super().__call__(observation)

    def _turned(self) -> bool:
        return np.linalg.norm(pin.log3(self.target @ self.env.state.ee_rotation.T)) < TURNED_WITHIN

    def place(self, goal: np.ndarray, grip: float):
        state, p = self.env.state, self.params
        cube = state.objects[p.object].position
        over = goal + [0.0, 0.0, p.drop]
        if self._turned() and np.linalg.norm(cube - over) < OVER_GOAL_WITHIN:
            self.releasing = True
            return self._release()
        return self.motion.toward(state.ee_position + (over - cube), self.target, grip, p.step)

    def _release(self):
        """Open where the hand is, then rise clear; a cube that did not land as the goal asks is tried again."""
        env, p, motion = self.env, self.params, self.motion
        state = env.state
        ee, cube = state.ee_position, state.objects[p.object].position
        if motion.gripper.closure(state.gripper) > 0.1:
            return motion.toward(ee, self.target, motion.gripper.open, p.step)
        if ee[2] < cube[2] + p.clearance - 0.02:
            return motion.toward(np.append(ee[:2], cube[2] + p.clearance), self.target, motion.gripper.open, p.step)
        tolerance = env.blueprint.spec.task.goal.tolerance
        if env.goal_parts.reached(env.achieved_goal(state), env.goal, tolerance):
            return motion.toward(ee, gripper=motion.gripper.open)
        self.reset()  # the turn it still needs, from where the cube now lies
        return super().__call__(None)
