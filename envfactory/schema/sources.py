"""Where each value of a composed spec was written: file and line per dotted path.

Hydra and OmegaConf drop line numbers, so the spec files are read once more
with PyYAML's node API, and every key is recorded under the package Hydra
merges it into. Later sources overwrite earlier ones, as in the merge.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import yaml

from envfactory.schema.errors import Problem, SpecError

try:  # the C loader is an order of magnitude faster where present
    from yaml import CSafeLoader as Loader
except ImportError:  # pragma: no cover
    from yaml import SafeLoader as Loader


@dataclass
class SourceMap:
    locations: dict[str, tuple[str, int]] = field(default_factory=dict)
    # path -> (origin, line): "gym.make kwarg x", or the registration entry's file and line
    notes: dict[str, tuple[str, int | None]] = field(default_factory=dict)
    # package (robot, task) -> the file the family's defaults list chose for it: a value that file does not
    # write is placed at the defaults line that chose it, and the message names the file
    chosen: dict[str, tuple[str, tuple[str, int]]] = field(default_factory=dict)

    def record_choice(self, package: str, file: Path, family: Path, line: int) -> None:
        """The defaults line of `family` that merges `file` into `package`."""
        self.chosen[package] = (str(file), (str(family), line))
        self.locations[package] = (str(family), line)

    def record_file(self, path: Path, package: str) -> yaml.Node | None:
        node = parse_yaml(path)
        if node is not None:
            self._walk(node, package, str(path), set(), 1)
        return node

    def _walk(self, node: yaml.Node, prefix: str, file: str, visited: set[int], used_at: int) -> None:
        """Record every key's line; `used_at` is the line where this node is used (an alias's)."""
        if isinstance(node, (yaml.MappingNode, yaml.SequenceNode)):
            # A block reused by alias is walked (and later merged) once per use: nested aliases
            # grow exponentially from a few lines, so spec files may not reuse blocks that way.
            if id(node) in visited:
                raise SpecError(
                    [
                        Problem(
                            prefix,
                            "YAML alias of a block (*name or <<: *name) is not supported in "
                            "spec files: use the defaults list or ${...} interpolation",
                            file,
                            used_at,
                        )
                    ],
                    Path(file).stem,
                )
            visited.add(id(node))
        if isinstance(node, yaml.MappingNode):
            seen: dict[str, int] = {}
            for key_node, value_node in node.value:
                key = str(key_node.value)
                line = key_node.start_mark.line + 1
                if key in seen:  # YAML would keep the last silently
                    path = f"{prefix}.{key}" if prefix else key
                    raise SpecError(
                        [Problem(path, f"duplicate key {key!r} (first written at line {seen[key]})", file, line)],
                        Path(file).stem,
                    )
                seen[key] = line
                if not prefix and key == "defaults":
                    continue
                path = f"{prefix}.{key}" if prefix else key
                self.locations[path] = (file, key_node.start_mark.line + 1)
                self.notes.pop(path, None)
                self._walk(value_node, path, file, visited, line)
        elif isinstance(node, yaml.SequenceNode):
            for index, item in enumerate(node.value):
                path = f"{prefix}.{index}"
                self.locations[path] = (file, item.start_mark.line + 1)
                # an aliased item starts where its anchor was written, above this use
                item_line = item.start_mark.line + 1
                self._walk(item, path, file, visited, item_line if item_line >= used_at else used_at)

    def note(self, path: str, origin: str, line: int | None = None) -> None:
        self.notes[path] = (origin, line)

    def locate(self, path: str) -> Problem:
        """A Problem shell at what set `path`: an override or kwarg that set it or a value below it (the file's
        line wrote only the rest), else the nearest recorded ancestor."""
        below = sorted(key for key in self.notes if key.startswith(path + "."))
        if below:
            origin, line = self.notes[below[0]]
            return Problem(path, "", file=origin, line=line)
        probe = path
        while True:
            if probe in self.notes:
                origin, line = self.notes[probe]
                return Problem(path, "", file=origin, line=line)
            if probe in self.locations:
                file, line = self.locations[probe]
                return Problem(path, "", file=file, line=line)
            if "." not in probe:
                return Problem(path, "")
            probe = probe.rsplit(".", 1)[0]

    def problem(self, path: str, message: str) -> Problem:
        shell = self.locate(path)
        package = path.split(".", 1)[0]
        if path != package and package in self.chosen and self._placed_at_choice(path, package):
            message += f" (not written in {self.chosen[package][0]}; this defaults line chose that file)"
        return Problem(path, message, file=shell.file, line=shell.line)

    def _placed_at_choice(self, path: str, package: str) -> bool:
        """Whether `path` is placed at the defaults line choosing its package: nothing below it was written."""
        probe = path
        while probe != package:
            if probe in self.notes or probe in self.locations:
                return False
            probe = probe.rsplit(".", 1)[0]
        return package not in self.notes and self.locations.get(package) == self.chosen[package][1]


class Findings:
    """The problems found in one spec, each placed where its value was written (file, line) and named by
    its dotted path: the one way the loader, the compiler, the scene and robot checks and the registry
    report a problem, so every message reads alike and all of them are raised at once."""

    def __init__(self, sources: SourceMap | None = None):
        self.sources = sources if sources is not None else SourceMap()
        self.problems: list[Problem] = []

    def add(self, path: str, message: str) -> None:
        self.problems.append(self.sources.problem(path, message))

    def where(self, path: str) -> str:
        """'path (file:line)': how a message names a second value it involves, the first being its own."""
        shell = self.sources.locate(path)
        if shell.file is None:
            return path
        return f"{path} ({shell.file}{f':{shell.line}' if shell.line is not None else ''})"

    def __bool__(self) -> bool:
        return bool(self.problems)

    def __iter__(self):
        return iter(self.problems)

    def raise_if_any(self, subject: str = "") -> None:
        if self.problems:
            raise SpecError(self.problems, subject)


def read_text(path: Path) -> str:
    """The file as UTF-8 text, or a SpecError that says why not."""
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise SpecError(
            [Problem("", f"not a text (UTF-8) file: byte {exc.start} cannot be decoded", str(path), 1)], path.stem
        ) from None
    except OSError as exc:
        raise SpecError([Problem("", f"cannot read: {exc.strerror or exc}", file=str(path))], path.stem) from None


def _parsed(path: Path, parse):
    text = read_text(path)
    try:
        return parse(text)
    except yaml.MarkedYAMLError as exc:
        raise SpecError([yaml_problem(exc, path)], path.stem) from None
    except yaml.YAMLError as exc:  # reader errors (control characters) carry no mark
        raise SpecError([Problem("", f"YAML: {str(exc).splitlines()[0]}", str(path), 1)], path.stem) from None
    except RecursionError:
        raise SpecError([Problem("", "YAML nested too deeply", str(path), 1)], path.stem) from None


def parse_yaml(path: Path) -> yaml.Node | None:
    return _parsed(path, lambda text: yaml.compose(text, Loader=Loader))


def load_plain(path: Path) -> dict:
    """The file's mapping, for the registry's quick scan (no composition)."""
    data = _parsed(path, lambda text: yaml.load(text, Loader=Loader))
    if not isinstance(data, dict):
        raise SpecError([Problem("", "a spec file must hold a mapping", file=str(path), line=1)])
    return data


def yaml_problem(exc: yaml.MarkedYAMLError, path: Path) -> Problem:
    mark = exc.problem_mark or exc.context_mark
    message = f"YAML syntax: {exc.problem or exc}"
    if exc.context and exc.context_mark is not None:
        message += f" ({exc.context} opened at line {exc.context_mark.line + 1})"
    return Problem("", message, file=str(path), line=mark.line + 1 if mark else None)
