"""Tell a user without the `[train]` extra what to install, instead of an ImportError."""

from __future__ import annotations

import importlib.util

# module -> the package that provides it
TRAIN_MODULES = {"torch": "torch", "stable_baselines3": "stable-baselines3", "sb3_contrib": "sb3-contrib"}
COLLECT_MODULES = {"minari": "minari"}
PLOT_MODULES = {"matplotlib": "matplotlib"}

# the extra asks for torch below 2.14 from whatever index pip uses (pyproject.toml says why the bound)
INSTALL_HINT = "pip install -e '.[train]' (from the envfactory checkout)"


class MissingExtra(RuntimeError):
    pass


def missing(modules: dict[str, str]) -> list[str]:
    return [package for module, package in modules.items() if importlib.util.find_spec(module) is None]


def require(modules: dict[str, str], what: str) -> None:
    absent = missing(modules)
    if absent:
        raise MissingExtra(
            f"{what} needs the [train] extra ({', '.join(absent)} not installed); install it with: {INSTALL_HINT}"
        )
