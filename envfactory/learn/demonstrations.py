"""Scripted-expert episodes as a Minari dataset (Farama's format for offline RL).

Each episode runs until the env itself ends it (the goal on sparse/goal envs,
the time limit otherwise), so the dataset's terminations and truncations are
the env's own. The expert acts in the env's action space (normalised when the
env is), so the recorded actions are what a learner would output.

With `action_noise` each action the expert gives is perturbed before the env
executes it, and the perturbed action is the one recorded (the transition is
what happened). The expert then acts from states off its own path and steers
back, so a learner cloning the dataset sees how to recover from its own small
errors (noise injection, as in DART: Laskey et al., 2017); the noise has zero
mean, so cloning still regresses on the expert's action.

Episodes are recorded by a small wrapper and handed to
`minari.create_dataset_from_buffers`: Minari's own DataCollector needs jax
(`minari[create]`) only to append steps, which this avoids.

A dataset of an ID from a user's spec folder records that folder in its
metadata (SPEC_FOLDER_KEY): a later process has not registered the ID, so
minari's `dataset.recover_environment()` alone cannot make it there;
`load_env(dataset)` registers the folder first, then recovers the env.
"""

from __future__ import annotations

import os
import re
import shutil
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

import gymnasium as gym
import numpy as np

from envfactory.envs.episodes import EpisodeResult, iter_episodes
from envfactory.experts import make_policy
from envfactory.learn import extra
from envfactory.registration import registry
from envfactory.schema.folders import folder_of
from envfactory.version import __version__

SPEC_FOLDER_KEY = "envfactory_spec_folder"  # dataset metadata: the user spec folder that declares its env ID
ACTION_NOISE_KEY = "envfactory_action_noise"  # dataset metadata: ActionNoise's std the episodes were recorded with
# the noise of an episode is drawn from (episode seed, this): its own stream, not the env's
NOISE_STREAM = 0x5EED_A0


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
        self._current = {
            "seed": seed,
            "observations": [observation],
            "actions": [],
            "rewards": [],
            "terminations": [],
            "truncations": [],
            "successes": [bool(info["is_success"])],
        }
        return observation, info

    def step(self, action):
        observation, reward, terminated, truncated, info = self.env.step(action)
        episode = self._current
        for key, value in (
            ("observations", observation),
            ("actions", np.asarray(action, np.float32)),
            ("rewards", float(reward)),
            ("terminations", bool(terminated)),
            ("truncations", bool(truncated)),
            ("successes", bool(info["is_success"])),
        ):
            episode[key].append(value)
        if terminated or truncated:
            self.episodes.append(episode)
        return observation, reward, terminated, truncated, info


class ActionNoise(gym.Wrapper):
    """Adds Gaussian noise to every action, of standard deviation `std` times each dimension's half-range, and
    clips the sum into the action space. Each episode's noise follows from its reset seed alone, so any split of
    the seeds across processes draws the same noise."""

    def __init__(self, env, std: float):
        super().__init__(env)
        space = env.action_space
        if not (isinstance(space, gym.spaces.Box) and np.all(np.isfinite(space.low) & np.isfinite(space.high))):
            raise ValueError(f"action noise needs a bounded Box action space, not {space}")
        self.std = float(std)
        self._scale = self.std * (space.high - space.low) / 2
        self._rng = np.random.default_rng(NOISE_STREAM)

    def reset(self, *, seed=None, options=None):
        if seed is not None:
            self._rng = np.random.default_rng([seed, NOISE_STREAM])
        return self.env.reset(seed=seed, options=options)

    def step(self, action):
        space = self.env.action_space
        noisy = np.asarray(action) + self._rng.normal(0.0, 1.0, space.shape) * self._scale
        return self.env.step(np.clip(noisy, space.low, space.high).astype(space.dtype))


def _stacked(items: list):
    """A list of Dict observations as a dict of lists, as Minari's buffers hold them."""
    if isinstance(items[0], dict):
        return {key: [item[key] for item in items] for key in items[0]}
    return items


def default_dataset_id(env_id: str) -> str:
    """`UR5eReacherGoalSim-v0` -> `envfactory/ur5ereachergoalsim/expert-v0`."""
    name = re.sub(r"-v\d+$", "", env_id).lower()
    return f"envfactory/{name}/expert-v0"


@dataclass
class Recording:
    """Whole episodes of the scripted expert on one env, ready for the dataset: the env's spec (with the
    kwargs it was made with) and the expert's name describe it; `episodes` are EpisodeRecorder's dicts and
    `results` the runner's, one per episode, in seed order."""

    env_spec: gym.envs.registration.EnvSpec
    expert: str
    episodes: list[dict]
    results: list[EpisodeResult]
    action_noise: float = 0.0  # ActionNoise's std, 0: the expert's own actions

    @staticmethod
    def merged(parts: list["Recording"]) -> "Recording":
        """Recordings of disjoint seed ranges as one, in seed order whatever order they came in, each
        episode numbered by its place in it: the recording of one process running every seed in turn."""
        pairs = sorted(
            (pair for part in parts for pair in zip(part.episodes, part.results)), key=lambda pair: pair[1].seed
        )
        return Recording(
            parts[0].env_spec,
            parts[0].expert,
            [e for e, _ in pairs],
            [replace(r, index=index) for index, (_, r) in enumerate(pairs)],
            parts[0].action_noise,
        )


def record(
    env_id: str, seeds: range, env_kwargs: dict | None = None, on_episode=None, action_noise: float = 0.0
) -> Recording:
    """The expert's episodes on `seeds` (a range of step 1), each whole, on a fresh env, with `action_noise`
    (ActionNoise's std) on its actions. An episode depends on its seed alone, so any split of the seeds across
    processes records the same episodes."""
    recorder = EpisodeRecorder(gym.make(env_id, **(env_kwargs or {})))
    # the noise goes outside the recorder: the recorded action is the one the env executed
    env = ActionNoise(recorder, action_noise) if action_noise else recorder
    try:
        expert = make_policy("scripted", env)
        results = []
        for result in iter_episodes(env, expert, len(seeds), seeds.start, stop_on_success=False):
            results.append(result)
            if on_episode is not None:
                on_episode(result)
        policy = env.unwrapped.blueprint.spec.task.expert.policy
        return Recording(recorder.env.spec, policy, recorder.episodes, results, float(action_noise))
    finally:
        env.close()


def collect(
    env_id: str,
    episodes: int,
    dataset_id: str | None = None,
    seed: int = 0,
    env_kwargs: dict | None = None,
    data_path: Path | None = None,
    overwrite: bool = False,
    on_episode=None,
    recorder=record,
    author: str | None = None,
    author_email: str | None = None,
    action_noise: float = 0.0,
) -> Collected:
    """Record `episodes` expert episodes (seeds seed, seed + 1, ...) and write them as a Minari dataset,
    with `action_noise` on the expert's actions (ActionNoise's std; 0: none).
    `recorder` runs the episodes (`record`'s signature); envfactory.cluster passes one that spreads them
    over Ray workers, and the dataset is the same."""
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
    if not 0 <= action_noise <= 1:
        raise ValueError(f"action noise {action_noise}: must be within 0..1 (a fraction of each action's half-range)")
    recording = recorder(env_id, range(seed, seed + episodes), env_kwargs, on_episode, action_noise)
    action_noise = recording.action_noise  # what the recorder applied, which the dataset then says
    noise = (
        f", with Gaussian noise of std {action_noise:g} times each action's half-range added to every action "
        f"(the recorded actions are the noisy ones the env executed)"
        if action_noise
        else ""
    )
    successes = sum(int(result.success) for result in recording.results)
    buffers = [
        EpisodeBuffer(
            id=index,
            seed=e["seed"],
            observations=_stacked(e["observations"]),
            actions=e["actions"],
            rewards=e["rewards"],
            terminations=e["terminations"],
            truncations=e["truncations"],
            # per step, so a learner can tell a demonstration that ends successful
            infos={"is_success": np.array(e["successes"])},
        )
        for index, e in enumerate(recording.episodes)
    ]
    try:
        with warnings.catch_warnings():
            for field, given in (("author", author), ("author_email", author_email)):
                if given is None:  # who runs collect is theirs to say (--author): never guessed, left out
                    warnings.filterwarnings("ignore", message=f"`{field}` is set to None", category=UserWarning)
            dataset = minari.create_dataset_from_buffers(
                dataset_id,
                buffers,
                env=recording.env_spec,
                eval_env=recording.env_spec,  # evaluate where collected
                author=author,
                author_email=author_email,
                code_permalink=f"envfactory {__version__}, envfactory/learn/demonstrations.py (collect)",
                algorithm_name=f"envfactory scripted expert ({recording.expert})"
                + (f", action noise {action_noise:g}" if action_noise else ""),
                description=f"{len(buffers)} episodes of the scripted expert on {env_id} with kwargs "
                f"{env_kwargs or {}}{noise}, seeds {seed}..{seed + len(buffers) - 1}, each run until the env "
                f"ends it (terminated or truncated); {successes} reach the goal, "
                f"{sum(e['successes'][-1] for e in recording.episodes)} end successful "
                f"(infos['is_success'] per step). Recover the env with "
                f"envfactory.learn.demonstrations.load_env(dataset).",
                data_format="hdf5",
            )
        dataset.storage.update_metadata({ACTION_NOISE_KEY: float(action_noise)})
        spec_folder = _user_spec_folder(env_id)
        if spec_folder is not None:
            dataset.storage.update_metadata({SPEC_FOLDER_KEY: spec_folder})
    except BaseException:
        shutil.rmtree(folder, ignore_errors=True)  # no half-written dataset blocks the next try
        raise
    steps = sum(len(e["actions"]) for e in recording.episodes)
    return Collected(dataset_id, Path(dataset.spec.data_path), len(recording.episodes), steps, successes)


def _user_spec_folder(env_id: str) -> str | None:
    """The spec folder declaring a user ID, absolute; None for a built-in ID (every process registers those)."""
    record = registry.record(env_id)
    if record.source == registry.BUILTIN_SOURCE:
        return None
    return str(folder_of(record.family.path).resolve())


class UnrecoverableEnv(LookupError):
    """A dataset's env ID is not registered and its spec folder cannot register it."""


def register_dataset_env(dataset) -> str:
    """Make the dataset's env ID known in this process, registering the spec folder `collect` recorded for a
    user ID (lazily, as ENVFACTORY_SPEC_PATH would); the ID."""
    env_id = dataset.env_spec.id
    if env_id in registry.records():
        return env_id
    folder = dataset.storage.metadata.get(SPEC_FOLDER_KEY)
    where = f"dataset {dataset.id}: its env {env_id}"
    if folder is None:
        raise UnrecoverableEnv(
            f"{where} is not registered and the dataset records no spec folder; register the "
            f"folder that declares it (envfactory.register_specs(PATH), `envfactory register "
            f"PATH` or {registry.SPEC_PATH_VARIABLE}) and load it again"
        )
    if not Path(folder).is_dir():
        raise UnrecoverableEnv(
            f"{where} comes from the spec folder {folder}, which no longer exists; register the "
            f"folder where it is now (envfactory.register_specs(PATH)) and load it again"
        )
    _, problems = registry.register_folder(folder)
    if env_id not in registry.records():
        found = "; ".join(registry.one_line(problem) for problem in problems) or "no family declares it"
        raise UnrecoverableEnv(f"{where} is not registered by its spec folder {folder}: {found}")
    return env_id


def load_env(dataset, eval_env: bool = False, **make_kwargs) -> gym.Env:
    """The env a dataset was collected on (`dataset`: a MinariDataset or its ID), as minari's
    `dataset.recover_environment(eval_env, **make_kwargs)` makes it, in any process: a user ID's spec folder,
    recorded by `collect`, is registered first."""
    extra.require(extra.COLLECT_MODULES, "load_env")
    import minari

    if isinstance(dataset, str):
        dataset = minari.load_dataset(dataset)
    register_dataset_env(dataset)
    return dataset.recover_environment(eval_env=eval_env, **make_kwargs)
