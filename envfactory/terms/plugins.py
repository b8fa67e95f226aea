"""Terms from a user's own Python: modules a spec names under `terms:`, or installed
packages that declare an `envfactory.terms` entry point. Importing such a module runs
its @observation_term / @reward_term / @termination_term decorators, which add the
terms to the library under their names."""

from __future__ import annotations

import importlib
import importlib.util
import logging
import sys
from importlib.metadata import entry_points
from pathlib import Path

ENTRY_POINT_GROUP = "envfactory.terms"
log = logging.getLogger("envfactory")
_plugins_loaded = False


def load_entry_points() -> None:
    """Import every installed `envfactory.terms` entry point, once; a broken one is one warning."""
    global _plugins_loaded
    if _plugins_loaded:
        return
    _plugins_loaded = True
    for entry in entry_points(group=ENTRY_POINT_GROUP):
        try:
            entry.load()
        except Exception as exc:  # a broken plugin must not break every env
            log.warning("envfactory: terms entry point %r (%s) failed to load: %s", entry.name, entry.value, exc)


def import_module(name: str, folder: Path) -> None:
    """Import a term module: `name.py` (or a package) beside the spec, else an installed module.
    Raises ImportError or whatever the module raises, with its own message."""
    if name in sys.modules:
        return
    relative = folder.joinpath(*name.split("."))
    for path in (relative.with_suffix(".py"), relative / "__init__.py"):
        if path.is_file():
            spec = importlib.util.spec_from_file_location(name, path)
            module = importlib.util.module_from_spec(spec)
            sys.modules[name] = module
            try:
                spec.loader.exec_module(module)
            except BaseException:
                del sys.modules[name]  # nothing half-imported stays behind
                raise
            return
    importlib.import_module(name)
