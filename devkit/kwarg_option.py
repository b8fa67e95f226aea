"""The benches' `-k NAME=VALUE` option, read as `envfactory`'s own -k reads it: the value is YAML, so numbers,
booleans and lists arrive typed. A value that is not YAML is refused when the command line is read, naming the
pair, rather than after a run has started (or inside a worker process)."""

from __future__ import annotations

import argparse

import yaml


def checked_pair(text: str) -> str:
    """argparse's type for one -k: the text itself, once it is known to read."""
    name, sep, value = text.partition("=")
    if not sep or not name:
        raise argparse.ArgumentTypeError(f"{text!r}: write name=value, e.g. -k engine=mujoco")
    try:
        yaml.safe_load(value)
    except yaml.YAMLError as exc:
        hint = "quote a value holding brackets, e.g. -k 'overrides=[\"workspace.min=[0, 0, 0.8]\"]'"
        raise argparse.ArgumentTypeError(
            f"{text!r}: the value is not valid YAML ({str(exc).splitlines()[0]}); {hint}"
        ) from None
    return text


def add_kwarg_option(parser: argparse.ArgumentParser, help: str = "gym.make kwarg as name=value, repeatable") -> None:
    # kept as text: some benches hand the pairs on to worker processes and print them in their reports
    parser.add_argument("-k", "--kwarg", action="append", default=[], type=checked_pair, help=help)


def kwargs_from(pairs: list[str]) -> dict:
    """The kwargs the -k pairs name (a later pair of the same name wins)."""
    return {name: yaml.safe_load(value) for name, _, value in (pair.partition("=") for pair in pairs)}
