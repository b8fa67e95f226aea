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
"""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium as gym
from ray.tune.registry import register_env

from envfactory.cluster.work import ShippedFolders
from envfactory.registration import registry

# keys RLlib itself puts into env_config (a vector env's size), which are no kwargs of the env
RLLIB_CONFIG_KEYS = ("num_envs",)
FLATTEN = "flatten_observation"  # the creator's own option (module docstring)


@dataclass(frozen=True)
class EnvCreator:
    """RLlib's env creator for one ID: env_config -> the env, in any process."""

    env_id: str
    workspace: ShippedFolders

    def __call__(self, env_config) -> gym.Env:
        self.workspace.enter([self.env_id])
        config = dict(env_config or {})
        flatten = config.pop(FLATTEN, False)
        if not isinstance(flatten, bool):
            raise ValueError(f"{self.env_id}: env_config {FLATTEN}={flatten!r} must be true or false")
        kwargs = {name: value for name, value in config.items() if name not in RLLIB_CONFIG_KEYS}
        env = gym.make(self.env_id, **kwargs)
        return gym.wrappers.FlattenObservation(env) if flatten else env


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
