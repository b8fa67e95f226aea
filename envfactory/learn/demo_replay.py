"""Demonstrations for training: a Minari dataset written by `envfactory collect`, checked against the env a run
trains on, then replayed into the run's replay buffer and into a buffer of its own for the cloning term.

Episodes go into the replay buffer one transition at a time through the buffer's own `add`, in order, each
episode closed by its last transition's end flag, so SB3's HerReplayBuffer knows where every demonstration
episode starts and ends and relabels its goals like any other episode. Observations are stored as the env gave
them and actions in the buffer's [-1, 1] scale, as SB3 stores its own transitions.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Iterator

import numpy as np

from envfactory.learn import extra
from envfactory.learn.demonstrations import ACTION_NOISE_KEY


class DemonstrationError(ValueError):
    """A demonstration dataset that cannot be used for this run (missing, unreadable, or for another env)."""


@dataclass
class Episode:
    observations: dict | np.ndarray  # n + 1 rows (a dict of arrays for a Dict space)
    actions: np.ndarray
    rewards: np.ndarray
    terminations: np.ndarray
    truncations: np.ndarray


@dataclass
class Demonstrations:
    reference: str  # as the user named it: a dataset ID or a folder
    dataset_id: str
    path: Path  # the dataset's data folder
    env_id: str | None
    env_kwargs: dict  # the gym.make kwargs it was collected with
    observation_space: object
    action_space: object
    episodes: list[Episode]
    action_noise: float = 0.0  # the noise on the expert's recorded actions (`envfactory collect --action-noise`)

    @property
    def transitions(self) -> int:
        return sum(len(e.actions) for e in self.episodes)

    def successful(self) -> "Demonstrations":
        """The episodes that reached the goal (their last step terminated), for a cloning term that clones only
        those."""
        kept = [e for e in self.episodes if bool(e.terminations[-1])]
        if not kept:
            raise DemonstrationError(
                f"--demos {self.reference}: none of its {len(self.episodes)} episodes reached the goal, and the run "
                f"clones only those (demos.clone_episodes=successful)"
            )
        return replace(self, episodes=kept)

    def summary(self) -> dict:
        """What model.json records, and what a resumed run checks the dataset against."""
        return {
            "reference": self.reference,
            "dataset_id": self.dataset_id,
            "path": str(self.path),
            "env_id": self.env_id,
            "env_kwargs": self.env_kwargs,
            "episodes": len(self.episodes),
            "transitions": self.transitions,
            "terminated": sum(bool(e.terminations[-1]) for e in self.episodes if len(e.actions)),
            "action_noise": self.action_noise,
        }


def _data_folder(reference: str) -> Path:
    """A folder given directly (the dataset's folder, or the `data` folder inside it), else an ID in Minari's
    datasets folder (MINARI_DATASETS_PATH, or ~/.minari/datasets)."""
    from minari.storage.datasets_root_dir import get_dataset_path

    given = Path(reference).expanduser()
    for folder in (given, given / "data"):
        if (folder / "metadata.json").is_file():
            return folder
    if given.exists():
        raise DemonstrationError(
            f"--demos {reference}: no Minari dataset in this folder (no metadata.json in it or in {given / 'data'})"
        )
    folder = get_dataset_path(reference) / "data"
    if not (folder / "metadata.json").is_file():
        raise DemonstrationError(
            f"--demos {reference}: no such dataset in {get_dataset_path()} (Minari's folder; "
            f"set MINARI_DATASETS_PATH or give the dataset's folder); write one with "
            f"`envfactory collect ID`"
        )
    return folder


def open_demonstrations(reference: str) -> Demonstrations:
    extra.require(extra.COLLECT_MODULES, "--demos")
    from minari import MinariDataset

    folder = _data_folder(reference)
    try:
        dataset = MinariDataset(folder)
        raw = list(dataset.iterate_episodes())
    except Exception as exc:  # h5py, json or Minari's own checks: the dataset, not the run, is at fault
        raise DemonstrationError(
            f"--demos {reference}: cannot read the dataset in {folder} ({type(exc).__name__}: {exc})"
        ) from None
    spec = dataset.spec.env_spec
    kwargs = {k: v for k, v in (spec.kwargs if spec else {}).items() if k != "env_id"}
    episodes = [
        Episode(
            e.observations,
            np.asarray(e.actions, np.float32),
            np.asarray(e.rewards, np.float32),
            np.asarray(e.terminations, bool),
            np.asarray(e.truncations, bool),
        )
        for e in raw
    ]
    demonstrations = Demonstrations(
        reference,
        dataset.spec.dataset_id,
        folder.resolve(),
        spec.id if spec else None,
        kwargs,
        dataset.observation_space,
        dataset.action_space,
        [e for e in episodes if len(e.actions)],  # a goal met at reset teaches nothing
        float(dataset.storage.metadata.get(ACTION_NOISE_KEY, 0.0)),  # datasets written before the key: none
    )
    if not demonstrations.episodes:
        raise DemonstrationError(f"--demos {reference}: the dataset holds no transitions")
    return demonstrations


def check_matches(demonstrations: Demonstrations, env_id: str, env_kwargs: dict, env) -> None:
    """The dataset must come from the env the run trains on: same ID, same kwargs, same spaces. Otherwise its
    actions would mean something else (another `delta_coeff`, joint instead of EE mode...)."""
    name = f"--demos {demonstrations.reference}"
    if demonstrations.env_id != env_id:
        raise DemonstrationError(f"{name}: collected on {demonstrations.env_id}, but this run trains {env_id}")
    if demonstrations.env_kwargs != env_kwargs:
        differ = sorted(
            k
            for k in set(demonstrations.env_kwargs) | set(env_kwargs)
            if demonstrations.env_kwargs.get(k, "unset") != env_kwargs.get(k, "unset")
        )
        flags = " ".join(f"-k {k}={v}" for k, v in env_kwargs.items())
        raise DemonstrationError(
            f"{name}: collected with kwargs {demonstrations.env_kwargs}, but this run makes {env_id} with "
            f"{env_kwargs} (they differ in {', '.join(differ)}); collect a matching dataset with "
            f"`envfactory collect {env_id} {flags} --dataset-id NEW_ID`"
        )
    for what, recorded, own in (
        ("observation", demonstrations.observation_space, env.observation_space),
        ("action", demonstrations.action_space, env.action_space),
    ):
        if recorded != own:
            raise DemonstrationError(
                f"{name}: its {what} space {recorded} is not the env's {own} (collected with "
                f"another version of the spec?)"
            )


def _row(observations, index: int):
    """One observation, shaped as a one-env VecEnv gives it (a leading axis of 1)."""
    if isinstance(observations, dict):
        return {key: np.asarray(value[index])[None] for key, value in observations.items()}
    return np.asarray(observations[index])[None]


def transitions(demonstrations: Demonstrations, scale_action) -> Iterator[tuple]:
    """(obs, next_obs, action, reward, done, infos) as a replay buffer's `add` takes them, episode by episode.
    An episode whose last step neither terminates nor truncates (a dataset cut short) ends as a truncation."""
    for episode in demonstrations.episodes:
        count = len(episode.actions)
        actions = scale_action(episode.actions)
        for t in range(count):
            terminated = bool(episode.terminations[t])
            truncated = not terminated and (bool(episode.truncations[t]) or t == count - 1)
            yield (
                _row(episode.observations, t),
                _row(episode.observations, t + 1),
                actions[t][None],
                np.array([episode.rewards[t]], np.float32),
                np.array([terminated or truncated]),
                [{"TimeLimit.truncated": truncated}],
            )  # SB3's flag: bootstrap through a time limit


def fill(buffer, demonstrations: Demonstrations, scale_action) -> int:
    """Add every demonstration transition to `buffer`; returns how many."""
    added = 0
    for item in transitions(demonstrations, scale_action):
        buffer.add(*item)
        added += 1
    return added


def cloning_buffer(demonstrations: Demonstrations, observation_space, action_space, scale_action, device="cpu"):
    """A buffer holding each demonstration transition once, for the cloning term's batches."""
    from gymnasium import spaces
    from stable_baselines3.common.buffers import DictReplayBuffer, ReplayBuffer

    kind = DictReplayBuffer if isinstance(observation_space, spaces.Dict) else ReplayBuffer
    buffer = kind(
        demonstrations.transitions, observation_space, action_space, device=device, handle_timeout_termination=False
    )
    fill(buffer, demonstrations, scale_action)
    return buffer
