"""Stable-Baselines3 on the native vector env: SB3VectorEnv presents a RobotVectorEnv (gym.make_vec of an ID) as
SB3's VecEnv, so N envs train in one process without SB3 making N gym envs of its own.

    vector = gym.make_vec("UR5ePushGoalSim-v0", num_envs=8, vectorization_mode="vector_entry_point")
    env = VecMonitor(SB3VectorEnv(vector))      # VecMonitor: episode returns in SB3's logs
    SAC("MultiInputPolicy", env, replay_buffer_class=HerReplayBuffer, ...)

SB3 resets an env in the step that ends its episode and hands the last observation over in
`info["terminal_observation"]`, with `info["TimeLimit.truncated"]` for a time limit; the adapter does that on the
vector env's one-env calls, whatever autoreset mode the vector env was made with.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from stable_baselines3.common.vec_env import VecEnv

from envfactory.envs.vector_env import RobotVectorEnv


class SB3VectorEnv(VecEnv):
    def __init__(self, vector: RobotVectorEnv):
        vector = getattr(vector, "unwrapped", vector)
        if not isinstance(vector, RobotVectorEnv):
            raise TypeError(
                f"SB3VectorEnv wraps envfactory's native vector env (gym.make_vec(ID, num_envs=N)), "
                f"not a {type(vector).__name__}"
            )
        self.vector = vector
        super().__init__(vector.num_envs, vector.single_observation_space, vector.single_action_space)
        self._actions: np.ndarray | None = None

    def reset(self):
        for index in range(self.num_envs):
            options = self._options[index] or None
            _, self.reset_infos[index] = self.vector.reset_one(index, self._seeds[index], options)
        self._reset_seeds()
        self._reset_options()
        return self.vector.batched_observations()

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self):
        rewards, dones, infos = np.zeros(self.num_envs, np.float32), np.zeros(self.num_envs, bool), []
        for index in range(self.num_envs):
            observation, rewards[index], terminated, truncated, info = self.vector.step_one(index, self._actions[index])
            info = dict(info)
            info["TimeLimit.truncated"] = truncated and not terminated
            dones[index] = terminated or truncated
            if dones[index]:
                info["terminal_observation"] = observation
                _, self.reset_infos[index] = self.vector.reset_one(index)  # its batch row: the new episode's first
            infos.append(info)
        return self.vector.batched_observations(), rewards, dones, infos

    def close(self) -> None:
        self.vector.close()

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        return [getattr(self.vector.envs[index], attr_name) for index in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        for index in self._get_indices(indices):
            setattr(self.vector.envs[index], attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        return [
            getattr(self.vector.envs[index], method_name)(*method_args, **method_kwargs)
            for index in self._get_indices(indices)
        ]

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]  # the vector env's envs are bare: nothing wraps them

    def get_images(self) -> list[np.ndarray | None]:
        return [env.render() for env in self.vector.envs]
