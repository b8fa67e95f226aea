"""envfactory: a config-driven factory of Gymnasium environments for robot arms.

Importing the package registers every env ID the spec folders declare (reading only their
registration blocks). The factory, which composes, compiles and builds envs, is imported on
first use of its names here, or by gymnasium at the first `gym.make`: it pulls in the
geometry, the physics and the term library, which an import that only lists IDs never needs.
"""

from importlib import import_module

from envfactory.registration.registry import records, register_on_import
from envfactory.schema.errors import SpecError
from envfactory.version import __version__

__all__ = ["SpecError", "__version__", "blueprint", "make_env", "records", "register_specs"]

_FACTORY_NAMES = {"blueprint", "make_env", "register_specs"}


def __getattr__(name: str):
    if name in _FACTORY_NAMES:
        return getattr(import_module("envfactory.factory"), name)
    raise AttributeError(f"module 'envfactory' has no attribute {name!r}")


register_on_import()
