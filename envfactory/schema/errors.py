"""Spec errors that say where: file, line and dotted path, with a suggestion."""

from __future__ import annotations

import difflib
from dataclasses import dataclass
from typing import Iterable


@dataclass(frozen=True)
class Problem:
    path: str  # dotted path in the composed spec, "" for the whole file
    message: str
    file: str | None = None
    line: int | None = None

    def __str__(self) -> str:
        where = self.file or "<spec>"
        if self.line is not None:
            where += f":{self.line}"
        return f"{where}: {self.path + ': ' if self.path else ''}{self.message}"


class SpecError(ValueError):
    """One or more problems in a spec; str() lists each on its own line."""

    def __init__(self, problems: Iterable[Problem], subject: str = ""):
        self.problems = list(problems)
        self.subject = subject
        header = f"invalid spec {subject}" if subject else "invalid spec"
        super().__init__(header + ":\n" + "\n".join(f"  {p}" for p in self.problems))


def nearest(name: str, valid: Iterable[str]) -> str | None:
    """The valid name nearest to `name`, if one is near enough to be what was meant."""
    close = difflib.get_close_matches(name, sorted(set(valid)), n=1, cutoff=0.6)
    return close[0] if close else None


def suggest(name: str, valid: Iterable[str]) -> str:
    """' (did you mean 'x'?)' for the nearest valid name, or the valid names."""
    valid = sorted(set(valid))
    close = nearest(name, valid)
    if close:
        return f" (did you mean {close!r}?)"
    if valid and len(valid) <= 30:
        return f" (valid: {', '.join(valid)})"
    return ""
