"""The user's config file: the spec folders `envfactory register` recorded, so every
later process (and gym.make after `import envfactory`) registers their IDs too.

The folder is user_folders.config_dir(): ENVFACTORY_CONFIG_DIR if set, else the platform's config folder.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from envfactory.user_folders import config_dir

FILE_NAME = "config.yaml"


class ConfigError(ValueError):
    """The config file exists but cannot be used."""


def config_file() -> Path:
    return config_dir() / FILE_NAME


def registered_folders() -> list[Path]:
    """The recorded spec folders, in the order they were added. Raises ConfigError for a
    file that is not ours to read."""
    path = config_file()
    if not path.is_file():
        return []
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise ConfigError(f"{path}: unreadable ({str(exc).splitlines()[0]})") from None
    folders = data.get("spec_folders", []) if isinstance(data, dict) else None
    if not isinstance(folders, list) or not all(isinstance(f, str) for f in folders):
        raise ConfigError(f"{path}: 'spec_folders' must be a list of folder paths")
    return [Path(f) for f in folders]


def _write(folders: list[Path]) -> None:
    path = config_file()
    path.parent.mkdir(parents=True, exist_ok=True)
    text = "# spec folders registered with `envfactory register`; `envfactory unregister` removes one\n"
    text += yaml.safe_dump({"spec_folders": [str(f) for f in folders]}, sort_keys=False)
    temporary = path.with_suffix(".tmp")
    temporary.write_text(text)
    temporary.replace(path)  # atomic: a crash never leaves half a file


def add_folder(folder: Path) -> bool:
    """Record a folder (absolute); False if it was already recorded."""
    folder = folder.expanduser().resolve()
    folders = registered_folders()
    if folder in folders:
        return False
    _write([*folders, folder])
    return True


def remove_folder(folder: Path) -> bool:
    """Forget a folder; False if it was not recorded."""
    folder = folder.expanduser().resolve()
    folders = registered_folders()
    if folder not in folders:
        return False
    _write([f for f in folders if f != folder])
    return True
