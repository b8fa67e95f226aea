"""RobotVectorEnv: N envs of one ID in one process, gymnasium's `vector_entry_point` of every registered ID.

What the N envs share is what never changes while they run: the compiled blueprint, the robot's kinematics and
collision tables (robot_geometry's cache) and, on MuJoCo, the compiled model (each env keeps its own MjData).
What each keeps is what a step changes: its backend's state, its safety check and its refusals, its goal, its
random generator. A randomized MuJoCo env rewrites its model's masses and frictions, so each builds its own;
PyBullet keeps one client per env (one world holding N robots would need every reading offset per env).

The envs step one after another on one core: the saving is in memory and in the processes an AsyncVectorEnv
would start, not in arithmetic (docs/benchmarks/vector_env.md measures both).
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space, concatenate, create_empty_array, iterate

from envfactory.compiler.compile import SIMULATORS
from envfactory.envs.robot_env import RobotEnv, env_for

Transition = tuple[Any, float, bool, bool, dict]


class RobotVectorEnv(VectorEnv):
    """`num_envs` envs of one blueprint, stepped in turn. Autoreset follows `autoreset_mode` as gymnasium 1.x
    defines it (next step by default; same step puts `final_obs`/`final_info` in the infos; disabled leaves
    resets to `reset(options={"reset_mask": mask})`). Each env ends its episode after `max_episode_steps`
    steps (truncated), as gym.make's time limit would."""

    def __init__(
        self,
        envs: Sequence[RobotEnv],
        max_episode_steps: int | None,
        autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
    ):
        if not envs:
            raise ValueError("a vector env needs at least one env (num_envs >= 1)")
        self.envs = list(envs)
        self.num_envs = len(self.envs)
        self.max_episode_steps = max_episode_steps
        self.autoreset_mode = AutoresetMode(autoreset_mode)
        first = self.envs[0]
        self.metadata = {**first.metadata, "autoreset_mode": self.autoreset_mode}
        self.render_mode = first.render_mode
        self.spec = None
        self.single_observation_space = first.observation_space
        self.single_action_space = first.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._elapsed = np.zeros(self.num_envs, dtype=np.int64)
        self._needs_reset = np.zeros(self.num_envs, dtype=bool)
        self._observations: list[Any] = [None] * self.num_envs

    # ------------------------------------------------------------ one env at a time (also the SB3 adapter's)

    def reset_one(self, index: int, seed: int | None = None, options: dict | None = None) -> tuple[Any, dict]:
        self._elapsed[index] = 0
        self._needs_reset[index] = False
        observation, info = self.envs[index].reset(seed=seed, options=options)
        self._observations[index] = observation
        return observation, info

    def step_one(self, index: int, action) -> Transition:
        """One env's step, with the time limit applied; no autoreset."""
        observation, reward, terminated, truncated, info = self.envs[index].step(action)
        self._elapsed[index] += 1
        if self.max_episode_steps is not None and self._elapsed[index] >= self.max_episode_steps:
            truncated = True
        self._needs_reset[index] = terminated or truncated
        self._observations[index] = observation
        return observation, float(reward), bool(terminated), bool(truncated), info

    # ------------------------------------------------------------ gymnasium's VectorEnv

    def reset(self, *, seed: int | Sequence[int | None] | None = None, options: dict | None = None):
        seeds = self._seeds(seed)
        options = dict(options or {})
        mask = options.pop("reset_mask", None)
        if mask is not None:
            mask = np.asarray(mask)
            if mask.shape != (self.num_envs,) or mask.dtype != np.bool_:
                raise ValueError(f"options['reset_mask'] must be a bool array of shape ({self.num_envs},)")
        infos: dict = {}
        for index in range(self.num_envs):
            if mask is None or mask[index]:
                _, info = self.reset_one(index, seeds[index], options or None)
                infos = self._add_info(infos, info, index)
        return self.batched_observations(), infos

    def step(self, actions):
        rewards = np.zeros(self.num_envs)
        terminations = np.zeros(self.num_envs, dtype=bool)
        truncations = np.zeros(self.num_envs, dtype=bool)
        infos: dict = {}
        for index, action in enumerate(iterate(self.action_space, actions)):
            if self._needs_reset[index] and self.autoreset_mode == AutoresetMode.NEXT_STEP:
                _, info = self.reset_one(index)
            elif self._needs_reset[index] and self.autoreset_mode == AutoresetMode.DISABLED:
                raise RuntimeError(
                    f"env {index} ended its episode and autoreset is disabled: reset it first "
                    "(reset(options={'reset_mask': mask}))"
                )
            else:
                observation, rewards[index], terminations[index], truncations[index], info = self.step_one(
                    index, action
                )
                if self.autoreset_mode == AutoresetMode.SAME_STEP and self._needs_reset[index]:
                    infos = self._add_info(infos, {"final_obs": observation, "final_info": info}, index)
                    _, info = self.reset_one(index)
            infos = self._add_info(infos, info, index)
        return self.batched_observations(), rewards, terminations, truncations, infos

    def render(self) -> tuple | None:
        if self.render_mode != "rgb_array":
            return None
        return tuple(env.render() for env in self.envs)

    def close_extras(self, **kwargs) -> None:
        for env in self.envs:
            env.close()

    def call(self, name: str, *args, **kwargs) -> tuple:
        """Each env's `name`: called with the arguments if callable, else read."""
        values = (getattr(env, name) for env in self.envs)
        return tuple(value(*args, **kwargs) if callable(value) else value for value in values)

    def get_attr(self, name: str) -> tuple:
        return tuple(getattr(env, name) for env in self.envs)

    def set_attr(self, name: str, values: Any) -> None:
        if not isinstance(values, (list, tuple)):
            values = [values] * self.num_envs
        if len(values) != self.num_envs:
            raise ValueError(f"set_attr({name!r}): {len(values)} values for {self.num_envs} envs")
        for env, value in zip(self.envs, values, strict=True):
            setattr(env, name, value)

    # ------------------------------------------------------------ goal envs: rewards pure in the goals

    def compute_reward(self, achieved_goal, desired_goal, info):
        return self.envs[0].compute_reward(achieved_goal, desired_goal, info)

    def compute_terminated(self, achieved_goal, desired_goal, info):
        return self.envs[0].compute_terminated(achieved_goal, desired_goal, info)

    # ------------------------------------------------------------ helpers

    def _seeds(self, seed) -> list[int | None]:
        if seed is None:
            return [None] * self.num_envs
        if isinstance(seed, (int, np.integer)):
            return [int(seed) + index for index in range(self.num_envs)]
        seeds = list(seed)
        if len(seeds) != self.num_envs:
            raise ValueError(f"reset(seed=...): {len(seeds)} seeds for {self.num_envs} envs")
        return seeds

    def batched_observations(self):
        """The envs' latest observations as one batch of the vector observation space."""
        if any(observation is None for observation in self._observations):
            raise RuntimeError("call reset() before step()")
        empty = create_empty_array(self.single_observation_space, self.num_envs)
        return concatenate(self.single_observation_space, self._observations, empty)


def build_envs(blueprint, num_envs: int, render_mode: str | None = None) -> list[RobotEnv]:
    """`num_envs` envs of one blueprint; on MuJoCo, unless randomized, the later ones run on the first's model."""
    if num_envs < 1:
        raise ValueError(f"num_envs must be at least 1, not {num_envs}")
    if num_envs > 1 and blueprint.backend not in SIMULATORS:
        # N envs over one robot's driver would each command the same arm
        raise ValueError(
            f"{blueprint.env_id}: a vector env of {num_envs} envs on the {blueprint.backend} backend would send "
            f"{num_envs} envs' commands to one robot; vector envs of more than one env are for the simulators "
            f"({', '.join(SIMULATORS)})"
        )
    first = env_for(blueprint, render_mode)
    shared = {}
    if blueprint.backend == "mujoco" and not blueprint.randomized:
        shared = {"built": first.backend.built}
    return [first, *(env_for(blueprint, render_mode, **shared) for _ in range(num_envs - 1))]


def vector_env(
    blueprint,
    num_envs: int,
    max_episode_steps: int | None,
    autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
    render_mode: str | None = None,
) -> RobotVectorEnv:
    return RobotVectorEnv(build_envs(blueprint, num_envs, render_mode), max_episode_steps, autoreset_mode)
