"""Tell a user without the `[train]` extra what to install, instead of an ImportError."""

from __future__ import annotations

import importlib.util

# module -> the package that provides it
TRAIN_MODULES = {"torch": "torch", "stable_baselines3": "stable-baselines3", "sb3_contrib": "sb3-contrib"}
COLLECT_MODULES = {"minari": "minari"}
PLOT_MODULES = {"matplotlib": "matplotlib"}

# the extra pins the CPU build of torch (torch==2.13.0+cpu on Linux): pip must find that wheel
# (--find-links or the PyTorch CPU package index) and never falls back to a CUDA build
INSTALL_HINT = "pip install -e '.[train]' (from the envfactory checkout; it needs the torch 2.13.0+cpu wheel)"


class MissingExtra(RuntimeError):
    pass


def missing(modules: dict[str, str]) -> list[str]:
    return [package for module, package in modules.items() if importlib.util.find_spec(module) is None]


def require(modules: dict[str, str], what: str) -> None:
    absent = missing(modules)
    if absent:
        raise MissingExtra(f"{what} needs the [train] extra ({', '.join(absent)} not installed); "
                           f"install it with: {INSTALL_HINT}")
