"""Per-family training hyperparameters, rl-zoo style: specs/train/<algo>.yaml.

Each file maps a key to a block of hyperparameters: `default`, a family name
(the spec file's stem, e.g. `ur5e_reach`) or an env ID. An ID's block is the
default, updated by its family's, updated by its own, updated by the command
line's `name=value` overrides (dotted names reach into nested blocks:
`policy_kwargs.net_arch=[64,64]`). A user spec folder may carry its own
`train/` beside its family files; their blocks win over the built-in ones.

Keys the trainer reads itself (everything else goes to the algorithm's
constructor): `n_timesteps`, `env_kwargs`, `her` (HER replay-buffer kwargs,
used on goal envs only), `normalize` (observations scaled by running statistics,
SB3's VecNormalize), `eval_every`, `eval_episodes`, `demos` (the behaviour-cloning
term of a run given demonstrations: bc.py).
"""

from __future__ import annotations

import copy
import re
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from envfactory.registration import registry
from envfactory.registration.registry import BUILTIN_SOURCE
from envfactory.schema.errors import suggest
from envfactory.schema.folders import builtin_root

ALGORITHMS = ("sac", "td3", "tqc")
TRAINER_KEYS = ("n_timesteps", "env_kwargs", "her", "normalize", "eval_every", "eval_episodes", "demos")


class HyperparameterError(ValueError):
    pass


# YAML 1.2's float: PyYAML follows YAML 1.1, which reads `3e-4` (no dot) as text, and SB3 would fail deep
# inside on the string
_FLOAT_TEXT = re.compile(r"[-+]?(\.[0-9]+|[0-9]+(\.[0-9]*)?)([eE][-+]?[0-9]+)")


def _numbers(value):
    """`value` with every float written YAML-1.2 style (`3e-4`) read as the number it is."""
    if isinstance(value, str) and _FLOAT_TEXT.fullmatch(value):
        return float(value)
    if isinstance(value, dict):
        return {k: _numbers(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_numbers(v) for v in value]
    return value


@dataclass
class Hyperparameters:
    algo: str
    values: dict
    sources: list[str] = field(default_factory=list)  # "file: key" of every block applied, in order

    def trainer(self, key: str, default=None):
        return self.values.get(key, default)

    def algorithm_kwargs(self) -> dict:
        return {k: v for k, v in self.values.items() if k not in TRAINER_KEYS}


def builtin_folder() -> Path:
    return builtin_root() / "specs" / "train"


def _folders(family_path: Path, builtin: bool) -> list[Path]:
    """Built-in first, then a user family's own folder (applied later, so it wins)."""
    own = family_path.parent / "train"  # beside the family file (in specs/ when the folder has one)
    return [builtin_folder()] + ([own] if not builtin and own.is_dir() else [])


def _read(path: Path) -> dict:
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"{path}:{mark.line + 1}" if mark else str(path)
        raise HyperparameterError(f"{where}: not valid YAML ({getattr(exc, 'problem', exc)})") from None
    if not isinstance(data, dict) or any(not isinstance(v, dict) for v in data.values()):
        raise HyperparameterError(
            f"{path}: must map keys (default, a family or an env ID) to blocks of hyperparameters"
        )
    return _numbers(data)


def merge(base: dict, update: dict) -> dict:
    """Nested blocks merge key by key; anything else is replaced."""
    out = copy.deepcopy(base)
    for key, value in update.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def parse_overrides(items: list[str]) -> dict:
    """`name=value` (value as YAML, dotted names nest) into a block to merge."""
    block: dict = {}
    for item in items:
        name, sep, text = item.partition("=")
        if not sep or not name:
            raise HyperparameterError(f"hyperparameter {item!r}: write name=value (e.g. learning_rate=3e-4)")
        try:
            value = yaml.safe_load(text)
        except yaml.YAMLError as exc:
            raise HyperparameterError(
                f"hyperparameter {item!r}: the value is not valid YAML ({str(exc).splitlines()[0]})"
            ) from None
        target = block
        *parents, leaf = name.split(".")
        for parent in parents:
            target = target.setdefault(parent, {})
            if not isinstance(target, dict):
                raise HyperparameterError(f"hyperparameter {item!r}: {parent} is set to a value and a block")
        target[leaf] = _numbers(value)
    return block


def _unread_files(family_path: Path, folders: list[Path]) -> list[str]:
    """Settings files a user put where they are never read: a train/ folder at the spec folder's root when the
    family files sit in specs/, and files in a read folder named for no algorithm."""
    found = []
    root = family_path.parent.parent if family_path.parent.name == "specs" else family_path.parent
    stray = root / "train"
    if stray.is_dir() and stray not in folders:
        found.append(
            f"{stray}: never read (training settings go beside the family files, in {family_path.parent / 'train'})"
        )
    for folder in folders[1:]:
        for path in sorted(folder.iterdir()):
            if path.suffix in (".yaml", ".yml") and path.name not in {f"{algo}.yaml" for algo in ALGORITHMS}:
                found.append(f"{path}: never read (a file is named for its algorithm: {', '.join(ALGORITHMS)}, .yaml)")
    return found


def _unknown_blocks(path: Path, data: dict) -> list[str]:
    """Blocks of a settings file that name no registered family or ID: a misspelled one would be skipped."""
    known = registry.records()
    names = ["default", *sorted({Path(r.family.path).stem for r in known.values()}), *sorted(known)]
    unknown = [key for key in data if key not in names]
    if not unknown:
        return []
    lines = path.read_text().splitlines()
    found = []
    for key in unknown:
        line = next((number for number, text in enumerate(lines, 1) if text.startswith(f"{key}:")), 1)
        found.append(f"{path}:{line}: block {key!r} names no family or env ID{suggest(str(key), names)}")
    return found


def load(algo: str, env_id: str, overrides: list[str] | tuple[str, ...] = ()) -> Hyperparameters:
    algo = algo.lower()
    if algo not in ALGORITHMS:
        raise HyperparameterError(f"algorithm {algo!r}: use one of {', '.join(ALGORITHMS)}")
    record = registry.record(env_id)
    family_path = Path(record.family.path)
    values: dict = {}
    sources: list[str] = []
    folders = _folders(family_path, record.source == BUILTIN_SOURCE)
    problems = _unread_files(family_path, folders) if record.source != BUILTIN_SOURCE else []
    for folder in folders:
        path = folder / f"{algo}.yaml"
        if not path.is_file():
            continue
        data = _read(path)
        problems += _unknown_blocks(path, data)
        for key in ("default", family_path.stem, env_id):
            if key in data:
                values = merge(values, data[key])
                sources.append(f"{path}: {key}")
    if problems:
        raise HyperparameterError("; ".join(problems))
    if not sources:
        raise HyperparameterError(f"no hyperparameters for {algo} ({builtin_folder() / (algo + '.yaml')} missing)")
    if overrides:
        values = merge(values, parse_overrides(list(overrides)))
        sources.append("command line: " + " ".join(overrides))
    return Hyperparameters(algo, values, sources)
