"""Train SAC, TD3 or TQC (Stable-Baselines3 / sb3-contrib) on an ID, HER on goal envs.

The run folder gets the saved model (`model.zip`), what it was trained on
(`model.json`: ID, algorithm, env kwargs, hyperparameters), and the learning
curve (`curve.csv`, `curve.png`): the success rate of deterministic episodes
on a separate env every `eval_every` steps, on the same evaluation goals each time.
With `normalize` the policy sees observations scaled by running statistics
(SB3's VecNormalize), saved beside the model (`vecnormalize.pkl`) for replay.
"""

from __future__ import annotations

import importlib
import inspect
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from envfactory.episodes import run_episodes
from envfactory.learn import extra
from envfactory.learn.curve import CurveWriter, Evaluation, plot
from envfactory.learn.hyperparams import HyperparameterError, Hyperparameters, load

ALGORITHM_CLASSES = {"sac": ("stable_baselines3", "SAC"), "td3": ("stable_baselines3", "TD3"),
                     "tqc": ("sb3_contrib", "TQC")}
EVAL_SEED = 10_000  # evaluation episode i resets with EVAL_SEED + i: the same goals at every evaluation
MODEL_FILE, META_FILE, CSV_FILE, PNG_FILE = "model.zip", "model.json", "curve.csv", "curve.png"
NORMALIZER_FILE = "vecnormalize.pkl"


def algorithm_class(algo: str):
    module, name = ALGORITHM_CLASSES[algo]
    return getattr(importlib.import_module(module), name)


class ModelPolicy:
    """A saved model as the callable policy the episode runner takes; with a normalizer (VecNormalize),
    observations are scaled as they were in training."""

    def __init__(self, model, normalizer=None):
        self.model = model
        self.normalizer = normalizer

    def reset(self) -> None:
        pass

    def __call__(self, observation):
        if self.normalizer is not None:
            observation = self.normalizer.normalize_obs(observation)
        action, _ = self.model.predict(observation, deterministic=True)
        return action


def evaluate(env, policy, episodes: int) -> tuple[float, float, float]:
    """Success rate, mean return and mean length of `episodes` episodes on the fixed evaluation seeds."""

    results = run_episodes(env, policy, episodes, seed=EVAL_SEED)
    n = len(results)
    return (sum(r.success for r in results) / n, sum(r.episode_return for r in results) / n,
            sum(r.length for r in results) / n)


@dataclass
class TrainResult:
    folder: Path
    evaluations: list[Evaluation]


def _algorithm_kwargs(cls, hyper: Hyperparameters, env) -> dict:
    kwargs = hyper.algorithm_kwargs()
    accepted = set(inspect.signature(cls.__init__).parameters)
    unknown = sorted(set(kwargs) - accepted - {"noise_std"})
    if unknown:
        raise HyperparameterError(f"{hyper.algo}: unknown hyperparameter(s) {', '.join(unknown)} (from "
                                  f"{'; '.join(hyper.sources)}); {cls.__name__} takes "
                                  f"{', '.join(sorted(accepted - {'self', 'env', 'policy'}))}")
    noise_std = kwargs.pop("noise_std", None)
    if noise_std is not None:
        import numpy as np
        from stable_baselines3.common.noise import NormalActionNoise

        size = env.action_space.shape[0]
        kwargs["action_noise"] = NormalActionNoise(np.zeros(size), float(noise_std) * np.ones(size))
    return kwargs


def make_model(env_id: str, hyper: Hyperparameters, env, seed: int, limit: int | None):
    """The algorithm on `env` (a gymnasium env, or a VecEnv around one); `limit` is the episode limit."""
    from stable_baselines3 import HerReplayBuffer

    cls = algorithm_class(hyper.algo)
    kwargs = _algorithm_kwargs(cls, hyper, env)
    goal_env = hasattr(env.observation_space, "spaces") and "desired_goal" in env.observation_space.spaces
    if goal_env:
        if limit and kwargs.get("learning_starts", 100) <= limit:
            # HER samples goals from finished episodes only: SB3 would fail at the first update
            raise HyperparameterError(f"{hyper.algo}: learning_starts={kwargs.get('learning_starts', 100)} must "
                                      f"exceed the episode limit of {env_id} ({limit} steps) with HER (from "
                                      f"{'; '.join(hyper.sources)})")
        kwargs["replay_buffer_class"] = HerReplayBuffer
        kwargs["replay_buffer_kwargs"] = dict(hyper.trainer("her") or {})
    policy = "MultiInputPolicy" if hasattr(env.observation_space, "spaces") else "MlpPolicy"
    return cls(policy, env, seed=seed, verbose=0, **kwargs)


def train(env_id: str, folder: Path, algo: str = "sac", seed: int = 0, steps: int | None = None,
          overrides: tuple[str, ...] = (), env_kwargs: dict | None = None, eval_every: int | None = None,
          eval_episodes: int | None = None, progress_bar: bool = True,
          on_evaluation: Callable[[Evaluation], None] | None = None) -> TrainResult:
    extra.require(extra.TRAIN_MODULES, "envfactory train")
    extra.require(extra.PLOT_MODULES, "the learning-curve plot")
    import gymnasium as gym
    import torch
    from stable_baselines3.common.callbacks import BaseCallback

    hyper = load(algo, env_id, overrides)
    steps = int(steps or hyper.trainer("n_timesteps", 30_000))
    eval_every = int(eval_every or hyper.trainer("eval_every", 5_000))
    eval_episodes = int(eval_episodes or hyper.trainer("eval_episodes", 50))
    kwargs = {**(hyper.trainer("env_kwargs") or {}), **(env_kwargs or {})}
    torch.set_num_threads(1)  # small networks: more threads only contend on a shared CPU
    folder.mkdir(parents=True, exist_ok=True)
    env, eval_env = gym.make(env_id, **kwargs), gym.make(env_id, **kwargs)
    try:
        env.reset(seed=seed)
        limit = env.spec.max_episode_steps if env.spec is not None else None
        normalizer = None
        if hyper.trainer("normalize", False):
            from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

            # goal coordinates vary by centimetres around offsets of a metre: unscaled, the networks
            # barely see the 2 cm that decide success (README, "Learning benchmark")
            normalizer = VecNormalize(DummyVecEnv([lambda: env]), norm_obs=True, norm_reward=False, clip_obs=10.0)
        model = make_model(env_id, hyper, normalizer or env, seed, limit)
        (folder / META_FILE).write_text(json.dumps(
            {"env_id": env_id, "algo": hyper.algo, "seed": seed, "steps": steps, "env_kwargs": kwargs,
             "hyperparameters": hyper.values, "sources": hyper.sources}, indent=2, default=str))
        writer = CurveWriter(folder / CSV_FILE)
        policy, start = ModelPolicy(model, normalizer), time.monotonic()

        def record(timesteps: int) -> None:
            success, mean_return, length = evaluate(eval_env, policy, eval_episodes)
            row = Evaluation(timesteps, success, mean_return, length, eval_episodes, time.monotonic() - start)
            writer.add(row)
            save(model, normalizer, folder)  # a run stopped later keeps the model of its last evaluation
            if on_evaluation is not None:
                on_evaluation(row)

        class EvaluateEvery(BaseCallback):
            def _on_step(self) -> bool:
                if self.num_timesteps % eval_every == 0:
                    record(self.num_timesteps)
                return True

        model.learn(steps, callback=EvaluateEvery(), progress_bar=progress_bar)
        if steps % eval_every:
            record(steps)
        save(model, normalizer, folder)
    finally:
        env.close()
        eval_env.close()
    plot({f"{hyper.algo.upper()} seed {seed}": writer.rows}, folder / PNG_FILE, f"{env_id} ({hyper.algo.upper()})")
    return TrainResult(folder, writer.rows)


def save(model, normalizer, folder: Path) -> None:
    model.save(folder / MODEL_FILE)
    if normalizer is not None:
        normalizer.save(str(folder / NORMALIZER_FILE))


def read_meta(path: Path) -> dict:
    """What a saved model was trained on (model.json beside model.zip), or {} when it is not there."""
    meta_path = path.with_suffix(".json")
    return json.loads(meta_path.read_text()) if meta_path.is_file() else {}


def load_policy(path: Path, env, algo: str | None = None) -> ModelPolicy:
    """A saved model, bound to `env` (HER models need the env; SB3 checks the spaces match)."""
    extra.require(extra.TRAIN_MODULES, "a --policy model")
    algo = (algo or read_meta(path).get("algo") or "").lower()
    if algo not in ALGORITHM_CLASSES:
        raise ValueError(f"{path}: which algorithm trained it? no {path.with_suffix('.json').name} beside it; "
                         f"pass --algo ({', '.join(ALGORITHM_CLASSES)})")
    normalizer = None
    if (path.parent / NORMALIZER_FILE).is_file():
        from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

        normalizer = VecNormalize.load(str(path.parent / NORMALIZER_FILE), DummyVecEnv([lambda: env]))
        normalizer.training = False  # replay reads the statistics, never updates them
    return ModelPolicy(algorithm_class(algo).load(path, env=env, device="cpu"), normalizer)
