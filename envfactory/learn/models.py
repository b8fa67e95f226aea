"""The algorithms (SAC, TD3 from Stable-Baselines3; TQC from sb3-contrib), built from the hyperparameters, and a
saved model loaded back as a policy. A run's files: `model.zip` and, with `normalize`, `vecnormalize.pkl` (SB3's
VecNormalize statistics) beside it; `model.json` beside them says what the model was trained on."""

from __future__ import annotations

import copy
import importlib
import json
from pathlib import Path

from envfactory.learn import extra
from envfactory.learn.bc import CloningSettings, cloning_class
from envfactory.learn.hyperparam_checks import check_algorithm_kwargs, check_trainer_values
from envfactory.learn.hyperparams import HyperparameterError, Hyperparameters, load

ALGORITHM_CLASSES = {
    "sac": ("stable_baselines3", "SAC"),
    "td3": ("stable_baselines3", "TD3"),
    "tqc": ("sb3_contrib", "TQC"),
}
MODEL_FILE, NORMALIZER_FILE = "model.zip", "vecnormalize.pkl"


def algorithm_class(algo: str, cloning: bool = False):
    """The algorithm's class; with `cloning`, carrying the behaviour-cloning term (bc.py)."""
    module, name = ALGORITHM_CLASSES[algo]
    base = getattr(importlib.import_module(module), name)
    return cloning_class(base) if cloning else base


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


def _algorithm_kwargs(cls, hyper: Hyperparameters, env) -> dict:
    kwargs = copy.deepcopy(hyper.algorithm_kwargs())  # the recorded hyperparameters stay as merged
    check_algorithm_kwargs(cls, hyper, kwargs)
    noise_std = kwargs.pop("noise_std", None)
    if noise_std is not None:
        import numpy as np
        from stable_baselines3.common.noise import NormalActionNoise

        size = env.action_space.shape[0]
        kwargs["action_noise"] = NormalActionNoise(np.zeros(size), float(noise_std) * np.ones(size))
    if kwargs.get("tensorboard_log") is not None:
        # absolute, so a resumed run (from any working folder) writes on in the same place
        kwargs["tensorboard_log"] = str(Path(kwargs["tensorboard_log"]).expanduser().resolve())
    return kwargs


def make_model(
    env_id: str, hyper: Hyperparameters, env, seed: int, limit: int | None, cloning: CloningSettings | None = None
):
    """The algorithm on `env` (a gymnasium env, or a VecEnv around one), and the kwargs its constructor got;
    `limit` is the episode limit; with `cloning`, the algorithm carries the behaviour-cloning term."""
    from stable_baselines3 import HerReplayBuffer

    base = algorithm_class(hyper.algo)
    cls = cloning_class(base) if cloning is not None else base
    kwargs = _algorithm_kwargs(base, hyper, env)  # the cloning term's own settings are not hyperparameters
    goal_env = hasattr(env.observation_space, "spaces") and "desired_goal" in env.observation_space.spaces
    if goal_env:
        if limit and kwargs.get("learning_starts", 100) <= limit:
            # HER samples goals from finished episodes only: SB3 would fail at the first update
            raise HyperparameterError(
                f"{hyper.algo}: learning_starts={kwargs.get('learning_starts', 100)} must "
                f"exceed the episode limit of {env_id} ({limit} steps) with HER (from "
                f"{'; '.join(hyper.sources)})"
            )
        kwargs["replay_buffer_class"] = HerReplayBuffer
        kwargs["replay_buffer_kwargs"] = dict(hyper.trainer("her") or {})
    if cloning is not None:
        kwargs.update(cloning.as_dict())
    policy = "MultiInputPolicy" if hasattr(env.observation_space, "spaces") else "MlpPolicy"
    passed = copy.deepcopy(kwargs)  # SB3 adds its own entries to policy_kwargs: keep what was asked for
    return cls(policy, env, seed=seed, verbose=0, **kwargs), passed


def checked_hyperparameters(algo: str, env_id: str, overrides=()) -> Hyperparameters:
    """The hyperparameters of a run to come, judged against its algorithm before any folder or env is made."""
    hyper = load(algo, env_id, overrides)
    extra.require(extra.TRAIN_MODULES, "training")
    check_algorithm_kwargs(algorithm_class(hyper.algo), hyper, copy.deepcopy(hyper.algorithm_kwargs()))
    check_trainer_values(hyper)
    return hyper


def save(model, normalizer, folder: Path) -> None:
    model.save(folder / MODEL_FILE)
    if normalizer is not None:
        normalizer.save(str(folder / NORMALIZER_FILE))


def read_meta(path: Path) -> dict:
    """What a saved model was trained on (model.json beside model.zip), or {} when it is not there."""
    meta_path = path.with_suffix(".json")
    return json.loads(meta_path.read_text()) if meta_path.is_file() else {}


class ModelMismatch(ValueError):
    """A saved model that cannot act in the env it was given: trained on other spaces, or no model at all."""


def load_policy(path: Path, env, algo: str | None = None) -> ModelPolicy:
    """A saved model, bound to `env` (HER models need the env); ModelMismatch names the env's spaces and SB3's
    reason when the model cannot act in it."""
    extra.require(extra.TRAIN_MODULES, "a --policy model")
    algo = (algo or read_meta(path).get("algo") or "").lower()
    if algo not in ALGORITHM_CLASSES:
        raise ValueError(
            f"{path}: which algorithm trained it? no {path.with_suffix('.json').name} beside it; "
            f"pass --algo ({', '.join(ALGORITHM_CLASSES)})"
        )
    normalizer = None
    if (path.parent / NORMALIZER_FILE).is_file():
        from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

        normalizer = VecNormalize.load(str(path.parent / NORMALIZER_FILE), DummyVecEnv([lambda: env]))
        normalizer.training = False  # replay reads the statistics, never updates them
    try:
        model = algorithm_class(algo).load(path, env=env, device="cpu")
    except Exception as exc:  # SB3 names the mismatching spaces; a zip that is no model lands here too
        space = env.observation_space
        shapes = {k: v.shape for k, v in space.spaces.items()} if hasattr(space, "spaces") else space.shape
        reason = str(exc).splitlines()[0][:160]
        raise ModelMismatch(
            f"{path}: cannot act in {env.spec.id if env.spec else env} (action shape {env.action_space.shape}, "
            f"observation shapes {shapes}): {type(exc).__name__}: {reason}; a model runs on the ID and kwargs it "
            f"was trained with (model.json beside it, or -k)"
        ) from exc
    return ModelPolicy(model, normalizer)
