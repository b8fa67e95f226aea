"""envfactory: a config-driven factory of Gymnasium environments for robot arms.

Importing the package registers every env ID the spec folders declare.
"""

from envfactory.registry import blueprint, make_env, register_specs, records
from envfactory.spec.errors import SpecError

__version__ = "0.1.0"

__all__ = ["SpecError", "blueprint", "make_env", "records", "register_specs"]


def _register_on_import() -> None:
    from envfactory.registry import register_on_import

    register_on_import()


_register_on_import()
