"""The package list in pyproject.toml names every wing of the library.

An editable install finds every subpackage through the folder mapping, so a wing
missing from the list only shows up on `pip install .`, as an ImportError on the
user's machine. This reads the list instead of building a wheel, to stay fast.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _declared_packages() -> set[str]:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    return set(config["packages"])


def _library_packages() -> set[str]:
    library = ROOT / "envfactory"
    return {
        ".".join(("envfactory",) + init.parent.relative_to(library).parts)
        for init in library.rglob("__init__.py")
        if "__pycache__" not in init.parts
    }


def test_every_library_package_is_listed():
    missing = _library_packages() - _declared_packages()
    assert not missing, f"pyproject.toml [tool.setuptools] packages lacks {sorted(missing)}"


def test_every_listed_package_exists():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    folders = config["package-dir"]
    for package in _declared_packages():
        top, _, rest = package.partition(".")
        mapped = folders.get(package)
        folder = ROOT / mapped if mapped else ROOT / "envfactory" / Path(*rest.split(".")) if rest else ROOT / top
        assert (folder / "__init__.py").is_file(), f"{package} is listed but {folder} has no __init__.py"
