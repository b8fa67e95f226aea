"""Every ID as an RLlib env, by its own name, with its gym.make kwargs in `env_config`:

    import envfactory, ray
    from envfactory.cluster import rllib
    from ray.rllib.algorithms.ppo import PPOConfig

    ray.init()
    rllib.register()  # after registering your own spec folders, if any
    config = (PPOConfig().environment("UR5eReacherGoalSim-v0",
                                      env_config={"ee_action_type": True, "flatten_observation": True})
              .env_runners(num_env_runners=4))
    algo = config.build_algo()
    algo.train()

RLlib sends each env creator to its env runners (pickled into the cluster's registry), so a runner on any
machine makes the env: an ID from a user spec folder carries a copy of that folder (bundles.py) and registers
it in the runner before the first make; the runner needs nothing from the head's working folder or
environment variables.

`env_config` holds the ID's gym.make kwargs, plus one option of the creator: `flatten_observation: True`
flattens a goal ID's Dict observation into one Box (gymnasium's FlattenObservation), as RLlib's default
models take Box observations.

With `.env_runners(num_envs_per_env_runner=N, gym_env_vectorize_mode=gym.VectorizeMode.VECTOR_ENTRY_POINT)`
RLlib asks the creator for N envs at once (`num_envs` in env_config), and each runner holds envfactory's native
vector env: N envs in its one process on one compiled blueprint and the robot's tables (MuJoCo: one model),
where RLlib's default "sync" mode makes N separate envs and "async" N processes.
"""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium as gym
from ray.tune.registry import register_env

from envfactory.cluster.work import ShippedFolders
from envfactory.registration import registry

VECTOR_SIZE = "num_envs"  # what RLlib's vector entry point adds to env_config: no kwarg of the env
FLATTEN = "flatten_observation"  # the creator's own option (module docstring)


@dataclass(frozen=True)
class EnvCreator:
    """RLlib's env creator for one ID: env_config -> the env, in any process."""

    env_id: str
    workspace: ShippedFolders

    def __call__(self, env_config) -> gym.Env | gym.vector.VectorEnv:
        self.workspace.enter([self.env_id])
        kwargs = dict(env_config or {})
        flatten = kwargs.pop(FLATTEN, False)
        if not isinstance(flatten, bool):
            raise ValueError(f"{self.env_id}: env_config {FLATTEN}={flatten!r} must be true or false")
        num_envs = kwargs.pop(VECTOR_SIZE, None)
        if num_envs is None:
            env = gym.make(self.env_id, **kwargs)
            return gym.wrappers.FlattenObservation(env) if flatten else env
        vector = gym.make_vec(self.env_id, num_envs=int(num_envs), vectorization_mode="vector_entry_point", **kwargs)
        return gym.wrappers.vector.FlattenObservation(vector) if flatten else vector


def register(env_ids: list[str] | None = None) -> list[str]:
    """Register `env_ids` (default: every ID registered in this process, the user folders' too) as RLlib envs
    under their own names; the IDs registered. Call it after ray.init, in the driver."""
    chosen = sorted(env_ids if env_ids is not None else registry.records())
    for env_id in chosen:
        registry.record(env_id)  # an unknown ID fails here, with the nearest known one
    workspace = ShippedFolders.for_ids(chosen)  # each user folder packed once, whatever the number of its IDs
    for env_id in chosen:
        register_env(env_id, EnvCreator(env_id, workspace))
    return chosen
