"""Training settings judged before anything is built: the names the algorithm's constructor takes, numbers where
its annotations ask for them, and values in the ranges it can learn with. SB3 takes a batch of 0, a discount of
1.5 or a negative buffer and runs, or fails deep inside its first update; each is named here with the blocks it
came from."""

from __future__ import annotations

import inspect
import math
import typing

from envfactory.learn.hyperparams import HyperparameterError, Hyperparameters
from envfactory.schema.numbers import is_number


def _number(value) -> bool:
    return is_number(value) and math.isfinite(value)


def _whole(value) -> bool:
    return _number(value) and float(value).is_integer()


def _entropy(value) -> bool:
    if isinstance(value, str):
        head, _, start = value.partition("_")
        return head == "auto" and (not start or _positive_text(start))
    return _number(value) and value >= 0


def _positive_text(text: str) -> bool:
    try:
        return float(text) > 0
    except ValueError:
        return False


def _train_freq(value) -> bool:
    if isinstance(value, (list, tuple)):
        return len(value) == 2 and _whole(value[0]) and value[0] >= 1 and value[1] in ("step", "episode")
    return _whole(value) and value >= 1


# name: (holds, what it must be); a value outside its range is refused before a run folder exists.
ALGORITHM_RANGES = {
    "learning_rate": (lambda v: _number(v) and v > 0, "a finite number above 0"),
    "gamma": (lambda v: _number(v) and 0 < v <= 1, "a discount in (0, 1]"),
    "tau": (lambda v: _number(v) and 0 < v <= 1, "a soft-update share in (0, 1]"),
    "batch_size": (lambda v: _whole(v) and v >= 1, "a whole number of at least 1"),
    "buffer_size": (lambda v: _whole(v) and v >= 1, "a whole number of at least 1"),
    "learning_starts": (lambda v: _whole(v) and v >= 0, "a whole number of at least 0"),
    "gradient_steps": (lambda v: _whole(v) and (v >= 1 or v == -1), "a whole number of at least 1, or -1"),
    "train_freq": (_train_freq, "a whole number of at least 1, or [n, step|episode]"),
    "policy_delay": (lambda v: _whole(v) and v >= 1, "a whole number of at least 1"),
    "target_policy_noise": (lambda v: _number(v) and v >= 0, "a finite number of at least 0"),
    "target_noise_clip": (lambda v: _number(v) and v >= 0, "a finite number of at least 0"),
    "noise_std": (lambda v: _number(v) and v >= 0, "a finite number of at least 0"),
    "top_quantiles_to_drop_per_net": (lambda v: _whole(v) and v >= 0, "a whole number of at least 0"),
    "ent_coef": (_entropy, "'auto', 'auto_START' or a finite number of at least 0"),
}
TRAINER_RANGES = {
    "n_timesteps": (lambda v: _whole(v) and v >= 1, "a whole number of steps, at least 1"),
    "eval_every": (lambda v: _whole(v) and v >= 1, "a whole number of steps, at least 1"),
    "eval_episodes": (lambda v: _whole(v) and v >= 1, "a whole number of episodes, at least 1"),
}


def _check_ranges(hyper: Hyperparameters, values: dict, ranges: dict) -> None:
    for name, value in values.items():
        if name in ranges and not ranges[name][0](value):
            raise HyperparameterError(
                f"{hyper.algo}: hyperparameter {name}={value!r} must be {ranges[name][1]} "
                f"(from {'; '.join(hyper.sources)})"
            )


def check_trainer_values(hyper: Hyperparameters) -> None:
    _check_ranges(hyper, hyper.values, TRAINER_RANGES)


def check_algorithm_kwargs(cls, hyper: Hyperparameters, kwargs: dict) -> None:
    """Names `cls` takes, numbers where it asks for them (a count written 1e6 becomes a whole number, in
    `kwargs`), in range."""
    accepted = set(inspect.signature(cls.__init__).parameters)
    unknown = sorted(set(kwargs) - accepted - {"noise_std"})
    if unknown:
        raise HyperparameterError(
            f"{hyper.algo}: unknown hyperparameter(s) {', '.join(unknown)} (from "
            f"{'; '.join(hyper.sources)}); {cls.__name__} takes "
            f"{', '.join(sorted(accepted - {'self', 'env', 'policy'}))}"
        )
    _check_types(cls, hyper, kwargs)
    _check_ranges(hyper, kwargs, ALGORITHM_RANGES)


def _check_types(cls, hyper: Hyperparameters, kwargs: dict) -> None:
    """Numbers where the constructor's annotation asks for one: on text (or a list) SB3 itself fails deep
    inside its first update, with no word of which hyperparameter it was."""
    where = f"from {'; '.join(hyper.sources)}"
    parameters = inspect.signature(cls.__init__).parameters
    for name, value in kwargs.items():
        wanted = float if name == "noise_std" else (parameters[name].annotation if name in parameters else None)
        choices = typing.get_args(wanted) or (wanted,)
        takes_text = str in choices or wanted in (None, inspect.Parameter.empty)
        number = is_number(value)
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
