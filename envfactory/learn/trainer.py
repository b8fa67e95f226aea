"""Train SAC, TD3 or TQC (Stable-Baselines3 / sb3-contrib) on an ID, HER on goal envs, optionally from
demonstrations (a Minari dataset of `envfactory collect`); continue a stopped run.

A new run only ever takes a free folder (runs.py), after everything that can refuse its settings has been
checked. The run folder gets the model (`model.zip`, models.py), the record of everything that shaped the run
(`model.json`, runs.py), the replay buffer and the learning curve (loop.py). `resume` continues a run from
those files, with the settings it was started with.
"""

from __future__ import annotations

import shlex
import warnings
from pathlib import Path
from typing import Callable

from envfactory.learn import extra
from envfactory.learn.bc import CloningSettings
from envfactory.learn.curve import CurveWriter, Evaluation
from envfactory.learn.demo_replay import check_matches, cloning_buffer, fill, open_demonstrations
from envfactory.learn.loop import BUFFER_FILE, CSV_FILE, PNG_FILE, WALL_PNG_FILE, Part, TrainResult, learn
from envfactory.learn.models import (
    MODEL_FILE,
    NORMALIZER_FILE,
    algorithm_class,
    checked_hyperparameters,
    load_policy,
    make_model,
    read_meta,
)
from envfactory.learn.runs import RECORD_FILE, RunFolderError, RunRecord, claim
from envfactory.learn.spec_folders import recorded_folder, register_recorded

META_FILE = RECORD_FILE
# what the CLI and `run --policy` take from here
__all__ = [
    "train",
    "resume",
    "load_policy",
    "read_meta",
    "TrainResult",
    "MODEL_FILE",
    "META_FILE",
    "CSV_FILE",
    "PNG_FILE",
    "WALL_PNG_FILE",
    "BUFFER_FILE",
    "NORMALIZER_FILE",
]
# SB3 warns when a loaded HER buffer ends inside an episode. A saved run always does (it stops at a step count,
# not at an episode's end), and a resumed run starts a new episode, so closing that one as truncated is right.
TRUNCATED_EPISODE_WARNING = r"The last trajectory in the replay buffer will be truncated"


def _recorded_kwargs(kwargs: dict) -> dict:
    """The constructor kwargs as model.json shows them (classes by name)."""
    return {k: (v.__name__ if isinstance(v, type) else v) for k, v in kwargs.items()}


def _command(
    env_id: str,
    algo: str,
    seed: int,
    steps: int,
    overrides,
    cli_kwargs: dict,
    eval_every: int,
    eval_episodes: int,
    demos: str | None,
) -> str:
    """The `envfactory train` command that repeats the run (the settings it resolves to are recorded too)."""
    words = [
        "envfactory",
        "train",
        env_id,
        "--algo",
        algo,
        "--seed",
        str(seed),
        "--steps",
        str(steps),
        "--eval-every",
        str(eval_every),
        "--eval-episodes",
        str(eval_episodes),
    ]
    words += [w for item in overrides for w in ("-p", item)]
    words += [w for k, v in cli_kwargs.items() for w in ("-k", f"{k}={v}")]
    words += ["--demos", demos] if demos else []
    return shlex.join(words)


def train(
    env_id: str,
    folder: Path,
    algo: str = "sac",
    seed: int = 0,
    steps: int | None = None,
    overrides: tuple[str, ...] = (),
    env_kwargs: dict | None = None,
    eval_every: int | None = None,
    eval_episodes: int | None = None,
    demos: str | None = None,
    progress_bar: bool = True,
    on_evaluation: Callable[[Evaluation], None] | None = None,
) -> TrainResult:
    """A new run in `folder`, which must be free (runs.fresh_folder picks one)."""
    extra.require(extra.TRAIN_MODULES, "envfactory train")
    extra.require(extra.PLOT_MODULES, "the learning-curve plot")
    import gymnasium as gym
    import torch

    hyper = checked_hyperparameters(algo, env_id, overrides)
    steps = int(steps or hyper.trainer("n_timesteps", 30_000))
    eval_every = int(eval_every or hyper.trainer("eval_every", 5_000))
    eval_episodes = int(eval_episodes or hyper.trainer("eval_episodes", 50))
    kwargs = {**(hyper.trainer("env_kwargs") or {}), **(env_kwargs or {})}
    cloning = CloningSettings.from_hyperparameters(hyper) if demos else None
    demonstrations = open_demonstrations(demos) if demos else None
    torch.set_num_threads(1)  # small networks: more threads only contend on a shared CPU
    env, eval_env = gym.make(env_id, **kwargs), gym.make(env_id, **kwargs)
    try:
        if demonstrations is not None:
            check_matches(demonstrations, env_id, kwargs, env)
        env.reset(seed=seed)
        limit = env.spec.max_episode_steps if env.spec is not None else None
        normalizer = None
        if hyper.trainer("normalize", False):
            from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

            # goal coordinates vary by centimetres around offsets of a metre: unscaled, the networks
            # barely see the 2 cm that decide success (README, "Learning benchmark")
            normalizer = VecNormalize(DummyVecEnv([lambda: env]), norm_obs=True, norm_reward=False, clip_obs=10.0)
        model, constructor_kwargs = make_model(env_id, hyper, normalizer or env, seed, limit, cloning)
        demo_summary = None
        if demonstrations is not None:
            cloned = _attach_demonstrations(model, demonstrations, seed_replay=True)
            demo_summary = {**demonstrations.summary(), "cloning": cloning.as_dict(), "cloned_episodes": cloned}
        created = claim(folder)  # last, after everything that can refuse the settings
        record = RunRecord(
            folder,
            {
                "env_id": env_id,
                "spec_folder": recorded_folder(env_id),
                "algo": hyper.algo,
                "seed": seed,
                "steps": steps,
                "eval_every": eval_every,
                "eval_episodes": eval_episodes,
                "env_kwargs": kwargs,
                "kwargs": dict(env_kwargs or {}),
                "overrides": list(overrides),
                "hyperparameters": hyper.values,
                "sources": hyper.sources,
                "algorithm_kwargs": _recorded_kwargs(constructor_kwargs),
                "normalize": normalizer is not None,
                "demos": demo_summary,
                "command": _command(
                    env_id, hyper.algo, seed, steps, overrides, dict(env_kwargs or {}), eval_every, eval_episodes, demos
                ),
                "timesteps": 0,
                "trained_s": 0.0,
                "tensorboard": None,
                "parts": [],
            },
        )
        run = Part(
            folder,
            record,
            model,
            normalizer,
            eval_env,
            steps,
            eval_every,
            eval_episodes,
            CurveWriter(folder / CSV_FILE),
            resumed=False,
            created=created,
        )
        return learn(run, progress_bar, on_evaluation)
    finally:
        env.close()
        eval_env.close()


def resume(
    folder: Path,
    steps: int | None = None,
    progress_bar: bool = True,
    on_evaluation: Callable[[Evaluation], None] | None = None,
) -> TrainResult:
    """Continue the run in `folder` up to `steps` in all (default: the run's own target), with its model,
    replay buffer, observation statistics, demonstrations and curve; its settings stay as recorded."""
    extra.require(extra.TRAIN_MODULES, "envfactory train --resume")
    extra.require(extra.PLOT_MODULES, "the learning-curve plot")
    import gymnasium as gym
    import torch

    record = RunRecord.read(folder)
    data = record.data
    register_recorded(data, folder)
    for name in (MODEL_FILE, BUFFER_FILE) + ((NORMALIZER_FILE,) if data.get("normalize") else ()):
        if not (folder / name).is_file():
            why = (
                (
                    " (a run saves it when it ends, is stopped with Ctrl-C or SIGTERM, or fails after its first "
                    "evaluation; this one was killed before it could)"
                )
                if name == BUFFER_FILE
                else ""
            )
            raise RunFolderError(f"{folder}: no {name}, so the run cannot continue{why}")
    target = int(steps or data.get("steps") or 0)
    done = int(data.get("timesteps") or 0)
    if data.get("replay_buffer_timesteps") != done:
        raise RunFolderError(
            f"{folder}: its {BUFFER_FILE} was saved at {data.get('replay_buffer_timesteps')} steps "
            f"but its model at {done} (the run was killed before it could save the buffer), so "
            f"the run cannot continue as it was"
        )
    if target <= done:
        raise RunFolderError(f"{folder}: the run is at {done} steps already; pass --steps above {done} to go on")
    torch.set_num_threads(1)
    env_id, kwargs = data["env_id"], data["env_kwargs"]
    env, eval_env = gym.make(env_id, **kwargs), gym.make(env_id, **kwargs)
    try:
        demonstrations = open_demonstrations(data["demos"]["path"]) if data.get("demos") else None
        if demonstrations is not None:
            _same_dataset(demonstrations, data["demos"], folder)
        normalizer = None
        if data.get("normalize"):
            from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

            normalizer = VecNormalize.load(str(folder / NORMALIZER_FILE), DummyVecEnv([lambda: env]))
        cls = algorithm_class(data["algo"], cloning=demonstrations is not None)
        model = cls.load(folder / MODEL_FILE, env=normalizer or env, device="cpu")
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=TRUNCATED_EPISODE_WARNING, category=UserWarning)
            model.load_replay_buffer(folder / BUFFER_FILE)
        if demonstrations is not None:
            _attach_demonstrations(model, demonstrations, seed_replay=False)  # the saved buffer holds them
        # a stream of its own per part, reproducible from the seed and the step it resumes at
        model.set_random_seed(int(data["seed"]) + model.num_timesteps)
        data["steps"] = target
        run = Part(
            folder,
            record,
            model,
            normalizer,
            eval_env,
            target,
            int(data["eval_every"]),
            int(data["eval_episodes"]),
            CurveWriter(folder / CSV_FILE, resume=True),
            resumed=True,
        )
        return learn(run, progress_bar, on_evaluation)
    finally:
        env.close()
        eval_env.close()


def _attach_demonstrations(model, demonstrations, seed_replay: bool) -> int:
    """Demonstrations into the replay buffer (a new run's) and into the cloning term's own buffer; the number of
    episodes cloned."""
    if seed_replay:
        fill(model.replay_buffer, demonstrations, model.policy.scale_action)
    if model.bc_weight == 0:
        return 0
    cloned = demonstrations.successful() if model.clone_episodes == "successful" else demonstrations
    model.attach_demonstrations(
        cloning_buffer(cloned, model.observation_space, model.action_space, model.policy.scale_action, model.device)
    )
    return len(cloned.episodes)


def _same_dataset(demonstrations, recorded: dict, folder: Path) -> None:
    found = demonstrations.summary()
    changed = [k for k in ("dataset_id", "episodes", "transitions") if found[k] != recorded.get(k)]
    if changed:
        raise RunFolderError(
            f"{folder}: the run learned from {recorded.get('path')} ({recorded.get('episodes')} "
            f"episodes, {recorded.get('transitions')} transitions), which now differs in "
            f"{', '.join(changed)}"
        )
