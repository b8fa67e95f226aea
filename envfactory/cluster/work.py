"""Episodes of one ID over a range of seeds: the work of one Ray task, and of the single process.

An episode depends on its seed alone (the env resets from the seed, the expert and a trained model act
deterministically), so a run's seeds may be split into ranges, run anywhere in any order, and merged by seed:
the episodes are those of one process running every seed in turn. A range's result holds whole episodes only,
so a worker that dies mid-range leaves nothing behind, and the range runs again on another.

Nothing here imports Ray: `EpisodeWork` objects are what the head sends (pickled) to the workers, and what
`run_here` runs in this process.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable

import gymnasium as gym

from envfactory.cluster.bundles import FolderCopy
from envfactory.envs.episodes import EpisodeResult, iter_episodes
from envfactory.experts import make_policy
from envfactory.learn.demonstrations import Recording, _user_spec_folder, record
from envfactory.learn.trainer import NORMALIZER_FILE, load_policy, read_meta
from envfactory.registration import registry
from envfactory.schema.folders import folder_of


class ShippedFoldersError(RuntimeError):
    """A job's spec folder cannot serve its IDs in this process."""


@dataclass(frozen=True)
class ShippedFolders:
    """The user spec folders a job's IDs come from, sent along with it (built-in IDs need none): for each
    user ID, the copy of the folder that declares it."""

    folders: tuple[tuple[str, FolderCopy], ...] = ()  # (env ID, its folder)

    @classmethod
    def for_ids(cls, env_ids: list[str]) -> "ShippedFolders":
        origins = {env_id: _user_spec_folder(env_id) for env_id in env_ids}
        copies = {folder: FolderCopy.pack(folder) for folder in set(origins.values()) if folder is not None}
        return cls(tuple((env_id, copies[folder]) for env_id, folder in sorted(origins.items()) if folder))

    def enter(self, env_ids: list[str]) -> None:
        """Make `env_ids` known in this process as the head knows them: each user ID from the folder sent
        along (registered lazily, as ENVFACTORY_SPEC_PATH would), never from another folder of this machine
        that declares the same ID."""
        sent = dict(self.folders)
        for env_id in env_ids:
            if env_id not in sent:
                if env_id not in registry.records():
                    raise ShippedFoldersError(
                        f"{env_id}: not registered in this process, and the job sent no spec folder declaring it"
                    )
                continue
            folder = sent[env_id].where()
            problems = [] if env_id in registry.records() else registry.register_folder(folder)[1]
            if env_id not in registry.records():
                found = "; ".join(registry.one_line(problem) for problem in problems) or "it declares no such ID"
                raise ShippedFoldersError(
                    f"{env_id}: its spec folder {sent[env_id].origin} (here {folder}) does not register it: {found}"
                )
            declared = folder_of(registry.record(env_id).family.path).resolve()
            if declared != folder.resolve():
                raise ShippedFoldersError(
                    f"{env_id}: this process registers it from {declared}, not from the job's "
                    f"spec folder {sent[env_id].origin} (here {folder}); leave the other folder "
                    f"out of this machine's ENVFACTORY_SPEC_PATH or `envfactory register`"
                )


MODEL_POLICY = "model"


@dataclass(frozen=True)
class PolicySource:
    """What acts in the episodes: the task's scripted expert, or a model saved by `envfactory train`, whose
    files (the model, its model.json, its observation statistics) travel with the job."""

    kind: str = "scripted"
    model: FolderCopy | None = None
    model_file: str = ""
    algo: str | None = None

    @classmethod
    def saved_model(cls, path: Path, algo: str | None = None) -> "PolicySource":
        path = Path(path).expanduser().resolve()
        names = (path.name, path.with_suffix(".json").name, NORMALIZER_FILE)
        return cls(MODEL_POLICY, FolderCopy.pack(path.parent, names), path.name, algo)

    @property
    def label(self) -> str:
        return f"{Path(self.model.origin) / self.model_file}" if self.kind == MODEL_POLICY else self.kind

    def trained_kwargs(self) -> dict:
        """The env kwargs the model was trained with (model.json); {} for the expert."""
        if self.kind != MODEL_POLICY:
            return {}
        return dict(read_meta(Path(self.model.origin) / self.model_file).get("env_kwargs", {}))

    def bind(self, env):
        """The policy acting in `env`."""
        if self.kind != MODEL_POLICY:
            return make_policy(self.kind, env)
        import torch

        # one thread in every process: a matrix product summed in another order by more threads could
        # change an action in its last bit, and the episode with it
        torch.set_num_threads(1)
        return load_policy(self.model.where() / self.model_file, env, self.algo)


@dataclass(frozen=True)
class EpisodeWork:
    """Episodes of `env_id` made with `env_kwargs`, over any range of seeds."""

    env_id: str
    env_kwargs: dict = field(default_factory=dict)
    workspace: ShippedFolders = ShippedFolders()

    def __call__(self, seeds: range, on_episode: Callable | None = None):
        self.workspace.enter([self.env_id])
        return self.run(seeds, on_episode)

    def run(self, seeds: range, on_episode: Callable | None):
        raise NotImplementedError

    def merge(self, parts: list):
        """The results of disjoint seed ranges as the results of one run over them all."""
        raise NotImplementedError


@dataclass(frozen=True)
class SeedEvaluation(EpisodeWork):
    """A policy's episodes, each until the env ends it (as `envfactory run` shows them): EpisodeResults."""

    policy: PolicySource = PolicySource()

    def run(self, seeds: range, on_episode: Callable | None) -> list[EpisodeResult]:
        env = gym.make(self.env_id, **self.env_kwargs)
        try:
            actor = self.policy.bind(env)
            results = []
            for result in iter_episodes(env, actor, len(seeds), seeds.start, stop_on_success=False):
                results.append(result)
                if on_episode is not None:
                    on_episode(result)
            return results
        finally:
            env.close()

    def merge(self, parts: list[list[EpisodeResult]]) -> list[EpisodeResult]:
        ordered = sorted((result for part in parts for result in part), key=lambda result: result.seed)
        return [replace(result, index=index) for index, result in enumerate(ordered)]


@dataclass(frozen=True)
class Collection(EpisodeWork):
    """The scripted expert's episodes, recorded whole for a Minari dataset: a Recording."""

    action_noise: float = 0.0  # demonstrations.ActionNoise's std

    def run(self, seeds: range, on_episode: Callable | None) -> Recording:
        return record(self.env_id, seeds, self.env_kwargs, on_episode, self.action_noise)

    def merge(self, parts: list[Recording]) -> Recording:
        return Recording.merged(parts)


def split(seeds: range, pieces: int) -> list[range]:
    """`seeds` as at most `pieces` consecutive ranges of near-equal length."""
    size = max(1, math.ceil(len(seeds) / max(1, pieces)))
    return [seeds[start : start + size] for start in range(0, len(seeds), size)]


def run_here(work: EpisodeWork, seeds: range, on_episode: Callable | None = None):
    """The work over `seeds` in this process, one seed after another: the reference a cluster run equals."""
    return work.merge([work(seeds, on_episode)])
