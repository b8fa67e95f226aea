"""Scripted-expert episodes as a Minari dataset (Farama's format for offline RL).

Each episode runs until the env itself ends it (the goal on sparse/goal envs,
the time limit otherwise), so the dataset's terminations and truncations are
the env's own. The expert acts in the env's action space (normalised when the
env is), so the recorded actions are what a learner would output.

Episodes are recorded by a small wrapper and handed to
`minari.create_dataset_from_buffers`: Minari's own DataCollector needs jax
(`minari[create]`) only to append steps, which this avoids.
"""

from __future__ import annotations

import os
import re
import shutil
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np

from envfactory.episodes import iter_episodes
from envfactory.experts import make_policy
from envfactory.learn import extra


@dataclass
class Collected:
    dataset_id: str
    path: Path
    episodes: int
    steps: int
    successes: int


class EpisodeRecorder(gym.Wrapper):
    """Keeps every finished episode's observations (n + 1), actions, rewards and end flags."""

    def __init__(self, env):
        super().__init__(env)
        self.episodes: list[dict] = []
        self._current: dict | None = None

    def reset(self, *, seed=None, options=None):
        observation, info = self.env.reset(seed=seed, options=options)
        self._current = {"seed": seed, "observations": [observation], "actions": [], "rewards": [],
                         "terminations": [], "truncations": [], "successes": [bool(info["is_success"])]}
        return observation, info

    def step(self, action):
        observation, reward, terminated, truncated, info = self.env.step(action)
        episode = self._current
        for key, value in (("observations", observation), ("actions", np.asarray(action, np.float32)),
                           ("rewards", float(reward)), ("terminations", bool(terminated)),
                           ("truncations", bool(truncated)), ("successes", bool(info["is_success"]))):
            episode[key].append(value)
        if terminated or truncated:
            self.episodes.append(episode)
        return observation, reward, terminated, truncated, info


def _stacked(items: list):
    """A list of Dict observations as a dict of lists, as Minari's buffers hold them."""
    if isinstance(items[0], dict):
        return {key: [item[key] for item in items] for key in items[0]}
    return items


def default_dataset_id(env_id: str) -> str:
    """`UR5eReacherGoalSim-v0` -> `envfactory/ur5ereachergoalsim/expert-v0`."""
    name = re.sub(r"-v\d+$", "", env_id).lower()
    return f"envfactory/{name}/expert-v0"


def collect(env_id: str, episodes: int, dataset_id: str | None = None, seed: int = 0,
            env_kwargs: dict | None = None, data_path: Path | None = None, overwrite: bool = False,
            on_episode=None) -> Collected:
    extra.require(extra.COLLECT_MODULES, "envfactory collect")
    if data_path is not None:
        # minari reads its datasets folder from the environment, at every call
        os.environ["MINARI_DATASETS_PATH"] = str(Path(data_path).resolve())
    import minari
    from minari.data_collector import EpisodeBuffer
    from minari.storage.datasets_root_dir import get_dataset_path

    dataset_id = dataset_id or default_dataset_id(env_id)
    folder = get_dataset_path(dataset_id)
    if folder.exists():
        if not overwrite:
            raise FileExistsError(f"dataset {dataset_id} already exists ({folder}); pass --overwrite to replace it")
        shutil.rmtree(folder)
    env = EpisodeRecorder(gym.make(env_id, **(env_kwargs or {})))
    try:
        expert = make_policy("scripted", env)
        successes = 0
        for result in iter_episodes(env, expert, episodes, seed, stop_on_success=False):
            successes += int(result.success)
            if on_episode is not None:
                on_episode(result)
        buffers = [EpisodeBuffer(id=index, seed=e["seed"], observations=_stacked(e["observations"]),
                                 actions=e["actions"], rewards=e["rewards"], terminations=e["terminations"],
                                 truncations=e["truncations"],
                                 # per step, so a learner can tell a demonstration that ends successful
                                 infos={"is_success": np.array(e["successes"])})
                   for index, e in enumerate(env.episodes)]
        expert_name = env.unwrapped.blueprint.spec.task.expert.policy
        try:
            dataset = minari.create_dataset_from_buffers(
                dataset_id, buffers, env=env.env.spec, algorithm_name=f"envfactory scripted expert ({expert_name})",
                description=f"{len(buffers)} episodes of the scripted expert on {env_id} with kwargs "
                            f"{env_kwargs or {}}, seeds {seed}..{seed + len(buffers) - 1}; {successes} reach the goal, "
                            f"{sum(e['successes'][-1] for e in env.episodes)} end successful (infos['is_success'] "
                            f"per step).",
                data_format="hdf5")
        except BaseException:
            shutil.rmtree(folder, ignore_errors=True)  # no half-written dataset blocks the next try
            raise
    finally:
        env.close()
    steps = sum(len(e["actions"]) for e in env.episodes)
    return Collected(dataset_id, Path(dataset.spec.data_path), len(env.episodes), steps, successes)
