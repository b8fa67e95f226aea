"""The algorithms (SAC, TD3 from Stable-Baselines3; TQC from sb3-contrib), built from the hyperparameters, and a
saved model loaded back as a policy. A run's files: `model.zip` and, with `normalize`, `vecnormalize.pkl` (SB3's
VecNormalize statistics) beside it; `model.json` beside them says what the model was trained on."""

from __future__ import annotations

import copy
import importlib
import inspect
import json
from pathlib import Path

from envfactory.learn import extra
from envfactory.learn.bc import CloningSettings, cloning_class
from envfactory.learn.hyperparams import HyperparameterError, Hyperparameters

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


def _check_types(cls, hyper: Hyperparameters, kwargs: dict) -> None:
    """Numbers where the constructor's annotation asks for one: on text (or a list) SB3 itself fails deep
    inside its first update, with no word of which hyperparameter it was."""
    import typing

    where = f"from {'; '.join(hyper.sources)}"
    parameters = inspect.signature(cls.__init__).parameters
    for name, value in kwargs.items():
        wanted = float if name == "noise_std" else (parameters[name].annotation if name in parameters else None)
        choices = typing.get_args(wanted) or (wanted,)
        takes_text = str in choices or wanted in (None, inspect.Parameter.empty)
        number = isinstance(value, (int, float)) and not isinstance(value, bool)
        if wanted in (int, float) and not number or (isinstance(value, str) and not takes_text):
            raise HyperparameterError(
                f"{hyper.algo}: hyperparameter {name} must be a number, got {value!r} ({type(value).__name__}; {where})"
            )
        if wanted is int and isinstance(value, float):
            if not value.is_integer():
                raise HyperparameterError(
                    f"{hyper.algo}: hyperparameter {name} must be a whole number, got {value!r} ({where})"
                )
            kwargs[name] = int(value)  # 1e6 written for a count


def _algorithm_kwargs(cls, hyper: Hyperparameters, env) -> dict:
    kwargs = copy.deepcopy(hyper.algorithm_kwargs())  # the recorded hyperparameters stay as merged
    accepted = set(inspect.signature(cls.__init__).parameters)
    unknown = sorted(set(kwargs) - accepted - {"noise_std"})
    if unknown:
        raise HyperparameterError(
            f"{hyper.algo}: unknown hyperparameter(s) {', '.join(unknown)} (from "
            f"{'; '.join(hyper.sources)}); {cls.__name__} takes "
            f"{', '.join(sorted(accepted - {'self', 'env', 'policy'}))}"
        )
    _check_types(cls, hyper, kwargs)
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
        raise ValueError(
            f"{path}: which algorithm trained it? no {path.with_suffix('.json').name} beside it; "
            f"pass --algo ({', '.join(ALGORITHM_CLASSES)})"
        )
    normalizer = None
    if (path.parent / NORMALIZER_FILE).is_file():
        from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

        normalizer = VecNormalize.load(str(path.parent / NORMALIZER_FILE), DummyVecEnv([lambda: env]))
        normalizer.training = False  # replay reads the statistics, never updates them
    return ModelPolicy(algorithm_class(algo).load(path, env=env, device="cpu"), normalizer)
