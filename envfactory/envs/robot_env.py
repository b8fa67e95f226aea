"""RobotEnv (Box observation) and GoalRobotEnv (Dict observation for HER).

The env is generic: everything robot- or task-specific arrives compiled in
the blueprint, and the physics or hardware sits behind a Backend.
"""

from __future__ import annotations

import logging

import gymnasium as gym
import numpy as np
import pinocchio as pin
from gymnasium import spaces
from gymnasium.error import ClosedEnvironmentError

from envfactory.backends import backend_factory
from envfactory.backends.base import BackendError, EpisodeAbort
from envfactory.backends.view import RENDER_SIZE
from envfactory.compiler import Blueprint
from envfactory.compiler.normalization import AffineScale
from envfactory.envs.actions import ActionAdapter
from envfactory.envs.goals import GoalSampler
from envfactory.envs.managers import ImageManager, ObservationManager, RewardManager, TerminationManager
from envfactory.envs.objects import ObjectSpawner, ObjectTracker
from envfactory.envs.randomization import Randomizer
from envfactory.envs.sim_limits import SimulationLimits
from envfactory.geometry.fixture_hold import FixtureHold
from envfactory.geometry.frames import TaskFrame
from envfactory.geometry.object_press import ObjectPressGuard
from envfactory.geometry.robot_model import robot_geometry
from envfactory.geometry.vectors import length
from envfactory.step_state import EnvState
from envfactory.terms.goal_parts import GoalParts
from envfactory.terms.rewards import STEP_FLAGS

log = logging.getLogger("envfactory")


class RobotEnv(gym.Env):
    """A gymnasium env over one blueprint and one backend, generic: it names no robot and no task. A step
    translates the action (ActionAdapter), has the safety check and the object guard judge it, plays it on the
    backend for one action cycle, reads the state, and computes the observation, reward and termination from the
    blueprint's terms. Box observation; GoalRobotEnv gives the Dict one for HER."""

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 2}

    def __init__(self, blueprint: Blueprint, render_mode: str | None = None, **backend_options):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode {render_mode!r} is not one of {self.metadata['render_modes']}")
        self.blueprint = blueprint
        self.render_mode = render_mode
        self._backend_options = backend_options
        spec = blueprint.spec
        robot = spec.robot
        self.metadata = {**self.metadata, "render_fps": 1.0 / spec.env.timing.action_cycle_time}
        self.task_frame = TaskFrame.of(robot)
        geometry = robot_geometry(
            spec, blueprint.asset_root, blueprint.fixture_folders
        )  # shared with every env of this robot
        self.safety = geometry.safety_check(spec.env.safety)  # this env's own: it measures and remembers
        self.kinematics = self.safety.kinematics
        self.actions = ActionAdapter(
            blueprint.action, self.kinematics, spec.workspace, spec.env.safety.max_joint_delta, robot
        )
        self.object_guard = (
            ObjectPressGuard(self.safety.collision, spec.task.objects, self.task_frame) if spec.task.objects else None
        )
        self.home = np.asarray(robot.home, float)
        self._ee_home = self.kinematics.ee_pose(self.home, spec.gripper_assumed_at_reset)[0]
        self.goal_parts = GoalParts.of(spec.task.goal)
        self.goals = GoalSampler(
            spec.task.goal,
            self.kinematics,
            self.safety,
            self.home,
            check_reach=blueprint.achieved_from == "ee",
            gripper=spec.gripper_assumed_at_reset,
        )
        self.rewards = RewardManager(blueprint.rewards, spec.task.goal.tolerance, blueprint.info_keys)
        self.terminations = TerminationManager(blueprint.terminations, spec.task.goal.tolerance, blueprint.info_keys)
        self.observations = ObservationManager(blueprint.policy_observation)
        self._vector_scale = self._goal_scale = None
        if spec.env.observation.normalize:  # normalize_observations
            self._vector_scale = AffineScale(self.observations.low, self.observations.high)
            self._goal_scale = AffineScale(*self.goal_parts.stacked_bounds(*spec.task.goal.box))
        self.images = ImageManager(blueprint.images, spec.scene.camera)
        self.action_space = spaces.Box(
            blueprint.action.policy_low.astype(np.float32),
            blueprint.action.policy_high.astype(np.float32),
            dtype=np.float32,
        )
        self.observation_space = self._observation_space()

        self._arm_in_states = np.array(robot.arm_state_indices)
        self._gripper_in_states = robot.gripper_state_index
        self._gripper_reset = spec.gripper_at_reset
        self.spawner = ObjectSpawner(spec.task.objects, spec.scene.table, self.task_frame)
        # fixtures are read as objects are: their moving link's pose, and their joint
        self._trackers = {name: ObjectTracker() for name in (*spec.task.objects, *spec.task.fixtures)}
        self.fixtures = geometry.fixtures
        self.fixture_hold = (
            FixtureHold(self.safety, self.fixtures, self.task_frame, robot.gripper) if self.fixtures else None
        )
        self.stage = blueprint.stage()  # the task's stage before the desired goal, if it declares one
        self._timing = spec.env.timing
        self._verbose = spec.env.log_internal_state
        self._seed_pending = spec.env.seed
        self._goal = np.zeros(self.goal_parts.size)
        self._goal_failed = False
        self._state: EnvState | None = None
        self._clipped: list[str] = []  # observation columns the last observation had to clip
        self._clip_logged: set[str] = set()  # columns whose clipping this env has logged (info flags each step)

        # only a backend that stands fixtures is told of them: others keep their signature, and the compiler
        # refuses fixtures on them
        fixtures = {"fixtures": geometry.fixtures} if geometry.fixtures else {}
        self.backend = backend_factory(blueprint.backend)(
            spec, geometry.urdf, self.task_frame, render_mode, **backend_options, **fixtures
        )
        self.backend.attach_geometry(self.safety.collision)
        # a simulator can leave its physics; a real arm's readings have their own checks on the real path
        self.sim_limits = SimulationLimits(spec.robot) if blueprint.backend != "rosbridge" else None
        self.randomizer = (
            Randomizer(blueprint, self.backend, self._timing.action_cycle_time) if blueprint.randomized else None
        )
        self._sensing_starts = False  # the next observation is an episode's first: the sensors start from it

    # ------------------------------------------------------------ spaces

    def _vector_space(self) -> spaces.Box:
        if self._vector_scale is not None:
            return self._vector_scale.box(self.observations.low, self.observations.high)
        return spaces.Box(self.observations.low, self.observations.high, dtype=np.float32)

    def _observation_space(self) -> spaces.Space:
        if not self.images:
            return self._vector_space()
        return spaces.Dict({"observation": self._vector_space(), **self.images.spaces()})

    # ------------------------------------------------------------ state

    def _read_state(self, previous_action: np.ndarray) -> EnvState:
        reading = self.backend.read_joints()
        q_arm = reading.position[self._arm_in_states]
        gripper = float(reading.position[self._gripper_in_states]) if self._gripper_in_states is not None else 0.0
        ee_position, ee_rotation = self.kinematics.ee_pose(q_arm, gripper)
        objects = {name: tracker.update(self.backend.read_object(name)) for name, tracker in self._trackers.items()}
        return EnvState(
            joint_positions=reading.position,
            joint_velocities=reading.velocity,
            q_arm=q_arm,
            gripper=gripper,
            ee_position=ee_position,
            ee_rotation=ee_rotation,
            ee_rpy=pin.rpy.matrixToRpy(ee_rotation),
            desired_goal=self._goal,
            current_goal=self._goal,
            previous_action=previous_action,
            objects=objects,
        )

    def _advance_stage(self, state: EnvState, achieved: np.ndarray) -> None:
        self.stage.update(achieved)
        state.current_goal = self.stage.current(self._goal)

    def achieved_goal(self, state: EnvState) -> np.ndarray:
        return self.goal_parts.achieved(state)

    def _vector(self, state: EnvState) -> np.ndarray:
        vector, self._clipped = self.observations.compute(state)
        if self.randomizer is not None:
            if self._sensing_starts:
                self.randomizer.start_sensing(vector, state.previous_action)
                self._sensing_starts = False
            # what the sensors make of it stays in the observation space (noise near a bound meets the bound)
            vector = np.clip(self.randomizer.observe(vector), self.observations.low, self.observations.high).astype(
                np.float32
            )
        # logged once per column and env: a column that keeps leaving its bounds would otherwise flood a
        # training run's output; info['observation_clipped'] still names it at every step
        first = [item for item in self._clipped if item.partition("=")[0] not in self._clip_logged]
        if first:
            self._clip_logged.update(item.partition("=")[0] for item in first)
            log.warning(
                "%s: observation outside its declared bounds, clipped and flagged in "
                "info['observation_clipped'] (logged once per column): %s",
                self.blueprint.env_id,
                ", ".join(first),
            )
        return vector if self._vector_scale is None else self._vector_scale.to_unit(vector).astype(np.float32)

    def _observe(self, state: EnvState):
        vector = self._vector(state)
        if not self.images:
            return vector
        return {"observation": vector, **self.images.capture(self.backend)}

    # ------------------------------------------------------------ gym API

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        self._refuse_if_closed("reset")
        # checked before anything moves: a real arm is not driven home for a goal that is refused
        chosen = (
            self.goals.given(options["goal"], f'{self.blueprint.env_id}.reset(options={{"goal": ...}})')
            if (options and "goal" in options)
            else None
        )
        if seed is None and self._seed_pending is not None:
            seed = self._seed_pending
        self._seed_pending = None
        super().reset(seed=seed)
        spawn = self.spawner.sample(self.np_random)
        self.backend.recover()  # a fault of the last episode never reaches this one
        if not self.backend.teleports_on_reset:
            # a real arm drives home: the whole way there must clear the table and floor
            reading = self.backend.read_joints().position
            gripper = float(reading[self._gripper_in_states]) if self._gripper_in_states is not None else 0.0
            # the gripper moves to its reset value on the way: the proof covers its whole range
            verdict = self.safety.path_is_clear(
                reading[self._arm_in_states],
                self.home,
                gripper,
                gripper if self._gripper_reset is None else self._gripper_reset,
            )
            if not verdict.accepted:
                raise BackendError(f"the move home is unsafe ({verdict.reason}); bring the arm clear by hand")
        self.backend.reset(self.home, self._gripper_reset, spawn)
        self.safety.forget()
        if self.fixture_hold is not None:
            self.fixture_hold.reset(self._gripper_reset)
        for tracker in self._trackers.values():
            tracker.reset()
        start = self._start_of(self.blueprint.achieved_from, spawn)
        goal, self._goal_failed = self.goals.sample(self.np_random, start)
        if chosen is not None:
            goal, self._goal_failed = chosen, False
        self._goal = self.goal_parts.expand(goal, self.np_random)
        if self.randomizer is not None:
            self.randomizer.reset(self.np_random)  # drawn after spawn and goal: those match an unrandomized env's
            self._sensing_starts = True
        self.backend.mark_goal(self.goal_parts.first(self._goal))
        self._state = self._read_state(np.zeros(self.action_space.shape, dtype=np.float32))
        self._state.previous_action = self.actions.hold_action(self._state)
        achieved = self.achieved_goal(self._state)
        self.stage.reset(spawn)
        self._advance_stage(self._state, achieved)
        observation = self._observe(self._state)
        return observation, self._info(self._state, achieved, out_of_bounds=False, rejection="")

    def step(self, action):
        self._refuse_if_closed("step")
        if self._state is None:
            raise RuntimeError("call reset() before step()")
        state = self._state
        action = self._checked_action(action)
        if self.randomizer is not None:
            self.randomizer.before_step()
            action = self.randomizer.act(action)  # a delayed action is judged and played when it lands
        command = self.actions.translate(action, state)
        rejection = command.rejection
        for name in self.fixtures:  # the drawer is where it was read: the check keeps the arm off it there
            self.safety.place_fixture(name, state.objects[name].joint)
        if self.fixture_hold is not None:
            rejection = rejection or self.fixture_hold.judge(state, command.q_arm, command.gripper).reason
        if not rejection:
            verdict = self.safety.check(state.q_arm, command.q_arm, state.gripper, command.gripper)
            rejection = verdict.reason
        if not rejection and self.object_guard is not None:
            gripper_to = state.gripper if command.gripper is None else command.gripper
            rejection = self.object_guard.check(
                state.q_arm, command.q_arm, state.gripper, gripper_to, self._free_objects(state)
            ).reason
        if rejection and self._verbose:
            log.info("%s: action rejected: %s", self.blueprint.env_id, rejection)
        previous = command.recorded
        try:
            if not rejection:
                self.backend.command_joints(command.q_arm, self._timing.action_speed)
                if command.gripper is not None:
                    self.backend.command_gripper(command.gripper)
                    if self.fixture_hold is not None:
                        self.fixture_hold.sent(command.gripper)
            self.backend.advance(self._timing.action_cycle_time)
            self._state = self._read_state(previous)
            if self.sim_limits is not None:
                self.sim_limits.check(self._state)
        except EpisodeAbort as exc:
            # stale or malformed readings, an arm that does not follow: the backend stopped it; the episode ends
            log.warning("%s: episode aborted: %s", self.blueprint.env_id, exc)
            return self._finish(state, command.out_of_bounds, rejection, truncated=True, abort=str(exc))
        except BaseException:
            self._stop_backend()  # any failure mid-step stops a real arm before it propagates
            raise
        return self._finish(self._state, command.out_of_bounds, rejection)

    def _start_of(self, name: str, spawn: dict) -> np.ndarray:
        """Where the achieved point starts an episode: an object's spawn, a fixture's point at its lower limit, or
        the EE at home."""
        if name in spawn:
            return spawn[name][0]
        if name in self.fixtures:
            return self.task_frame.to_task(self.fixtures[name].point)
        return self._ee_home

    def _free_objects(self, state: EnvState) -> dict:
        return (
            {name: state.objects[name] for name in self.blueprint.spec.task.objects} if self.fixtures else state.objects
        )

    def _checked_action(self, action) -> np.ndarray:
        """The action as an array of the action space's shape; anything else is refused before it moves the arm."""
        array = np.asarray(action)
        if array.shape != self.action_space.shape or array.dtype.kind not in "fiu":  # float, signed or unsigned int
            raise ValueError(
                f"{self.blueprint.env_id}: the action has shape {array.shape} and dtype {array.dtype}; "
                f"the action space is {self.action_space}: nothing was sent to the arm"
            )
        return array

    def _stop_backend(self) -> None:
        try:
            self.backend.stop()
        except Exception as exc:  # the original failure matters more; say this one too
            log.error("%s: could not send the stop: %s", self.blueprint.env_id, exc)

    def _finish(self, state: EnvState, out_of_bounds: bool, rejection: str, truncated: bool = False, abort: str = ""):
        achieved = self.achieved_goal(state)
        self._advance_stage(state, achieved)
        observation = self._observe(state)
        info = self._info(state, achieved, out_of_bounds, rejection)
        if abort:
            info["abort_reason"] = abort
        reward = float(self.rewards.reward(achieved, self._goal, info))
        terminated = bool(self.terminations.terminated(achieved, self._goal, info))
        return observation, reward, terminated, truncated, info

    def _info(self, state: EnvState, achieved: np.ndarray, out_of_bounds: bool, rejection: str) -> dict:
        # the farthest part's: success is every part within tolerance
        parts, tolerance = self.goal_parts, self.blueprint.spec.task.goal.tolerance
        if len(parts.names) == 1 and not parts.turned:  # most tasks' goal: one point, measured the fast way
            distance = length(achieved - self._goal)
            success = distance < tolerance
        else:  # the farthest point part's distance; success is every part within its tolerance
            distance = float(parts.distances(achieved, self._goal).max())
            success = bool(parts.reached(achieved, self._goal, tolerance))
        flags = (out_of_bounds, bool(rejection), self._goal_failed)
        info = {key: float(value) for key, value in zip(STEP_FLAGS, flags, strict=True)}
        info.update(
            rejection_reason=rejection,
            observation_clipped=list(self._clipped),
            distance=distance,
            is_success=success,
        )
        if parts.turned:
            info["angle"] = float(parts.angles(achieved, self._goal).max())
        info.update(self.stage.info(self._goal))
        info.update(self.rewards.measure(state))
        if self.randomizer is not None:
            info["randomization"] = dict(self.randomizer.values)
        timing = self.backend.step_timing()
        if timing:
            info["timing"] = timing
        return info

    def render(self):
        if self.render_mode == "rgb_array":
            return self.backend.render(*RENDER_SIZE)
        return None

    def close(self):
        backend = getattr(self, "backend", None)
        if backend is not None:
            backend.close()
        self._closed = True
        super().close()

    def _refuse_if_closed(self, call: str) -> None:
        if getattr(self, "_closed", False):
            raise ClosedEnvironmentError(
                f"{self.blueprint.env_id}.{call}() after close(): its {type(self.backend).__name__} is shut; "
                "make a new env"
            )

    # ------------------------------------------------------------ copies

    def __getstate__(self) -> dict:
        """A copy (pickle or deepcopy) is a fresh env of the same blueprint, not a snapshot of the physics:
        it opens its own backend (a new PyBullet client), starts un-reset, and carries over the random
        generator's state, so its next reset() samples what this env's next reset() would."""
        return {
            "blueprint": self.blueprint,
            "render_mode": self.render_mode,
            "backend_options": self._backend_options,
            "np_random_state": self._np_random.bit_generator.state if self._np_random is not None else None,
            "np_random_seed": self._np_random_seed,
            "seed_pending": self._seed_pending,
            "spec": self.spec,
        }

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["blueprint"], render_mode=state["render_mode"], **state["backend_options"])
        if state["np_random_state"] is not None:
            self._np_random = np.random.Generator(np.random.PCG64())
            self._np_random.bit_generator.state = state["np_random_state"]
            self._np_random_seed = state["np_random_seed"]
        self._seed_pending = state["seed_pending"]
        self.spec = state["spec"]

    # ------------------------------------------------------------ introspection

    @property
    def goal(self) -> np.ndarray:
        """The desired goal: every part's point in turn (task.goal.also), the first part's alone in most tasks."""
        return self._goal.copy()

    def goal_of(self, name: str) -> np.ndarray:
        """One part's desired goal: the EE's or an object's."""
        return self.goal_parts.part(self._goal, self.goal_parts.index(name)).copy()

    @property
    def state(self) -> EnvState | None:
        return self._state


class GoalRobotEnv(RobotEnv):
    """Dict observation for goal-conditioned learning; rewards pure in the goals."""

    def _observation_space(self) -> spaces.Space:
        spec = self.blueprint.spec
        # in float64 until the scale has mapped them: a flat goal axis (a goal on the table top) cast to float32
        # first maps to -2e-10, and the 0.0 every goal on it maps to would lie outside its own space
        goal_low, goal_high = self.goal_parts.stacked_bounds(*spec.task.goal.box)
        achieved_low, achieved_high = self.goal_parts.achieved_bounds(self.blueprint.boxes)
        box = (
            self._goal_scale.box
            if self._goal_scale is not None
            else (lambda low, high: spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32))
        )
        return spaces.Dict(
            {
                "observation": self._vector_space(),
                "achieved_goal": box(achieved_low, achieved_high),
                "desired_goal": box(goal_low, goal_high),
                **self.images.spaces(),
            }
        )

    def _observe(self, state: EnvState):
        achieved, desired = self.achieved_goal(state), self._goal
        if self._goal_scale is not None:
            achieved, desired = self._goal_scale.to_unit(achieved), self._goal_scale.to_unit(desired)
        return {
            "observation": self._vector(state),
            "achieved_goal": achieved.astype(np.float32),
            "desired_goal": desired.astype(np.float32),
            **self.images.capture(self.backend),
        }

    def _in_metres(self, achieved_goal, desired_goal):
        if self._goal_scale is None:
            return achieved_goal, desired_goal
        return self._goal_scale.from_unit(achieved_goal), self._goal_scale.from_unit(desired_goal)

    def compute_reward(self, achieved_goal, desired_goal, info):
        return self.rewards.reward(*self._in_metres(achieved_goal, desired_goal), info)

    def compute_terminated(self, achieved_goal, desired_goal, info):
        return self.terminations.terminated(*self._in_metres(achieved_goal, desired_goal), info)

    def compute_truncated(self, achieved_goal, desired_goal, info):
        # truncation is the registered time limit's job
        return np.zeros(np.asarray(achieved_goal).shape[:-1], dtype=bool)


def env_for(blueprint: Blueprint, render_mode: str | None = None, **backend_options) -> RobotEnv:
    """The env of a blueprint: the Dict-observation GoalRobotEnv for a goal env, else a RobotEnv."""
    env_class = GoalRobotEnv if blueprint.goal_env else RobotEnv
    return env_class(blueprint, render_mode=render_mode, **backend_options)
