"""Jobs and envs on a Ray cluster: episodes of `collect` and `evaluate` as Ray tasks, training trials as Ray
Tune trials, every ID as an RLlib env.

The one wing that knows Ray. Its modules that use Ray (`pool`, `tuning`, `rllib`) import it at their top, and
nothing outside the wing imports them statically: the commands load them with `load` below, only when asked
for workers, so that every command works without Ray and the CLI does not pay for importing it. The modules
without Ray (`bundles`, `work`) describe the work and run it, in one process or in a worker alike: the same
code runs an episode either way, which is why a run spread over workers gives the single process's episodes.
"""

from __future__ import annotations

import importlib
from types import ModuleType

from envfactory.learn.extra import MissingExtra, missing

RAY_MODULES = {"ray": "ray"}  # module -> the package that provides it
RAY_INSTALL_HINT = "pip install 'envfactory[ray]'"


def require_ray(what: str) -> None:
    """Raise MissingExtra, saying how to install the [ray] extra, when Ray is not installed."""
    absent = missing(RAY_MODULES)
    if absent:
        raise MissingExtra(
            f"{what} needs the [ray] extra ({', '.join(absent)} not installed); install it with: {RAY_INSTALL_HINT}"
        )


def load(module: str, what: str) -> ModuleType:
    """envfactory.cluster.MODULE, which imports Ray; MissingExtra (naming `what`) when Ray is not installed."""
    require_ray(what)
    return importlib.import_module(f"{__name__}.{module}")
