"""The `envfactory` command's application object and what every command shares: the error guard that
turns any escaping error into one message, output-path and kwarg checks, the consoles."""

from __future__ import annotations

import functools
import os
import sys
from pathlib import Path
from typing import List

import typer
import yaml
from rich.console import Console
from rich.markup import escape

from envfactory import registry
from envfactory.schema.errors import SpecError

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
                  help="A config-driven factory of Gymnasium environments for robot arms.")
# Tables stay whole when the output is piped or captured.
_WIDTH = None if sys.stdout.isatty() else 140
console = Console(width=_WIDTH)
errors = Console(stderr=True, width=_WIDTH)
_debug = {"on": False}


def _fail(message: str, code: int = 1) -> None:
    # the message is plain text: brackets in it ([train], list values) are not markup
    errors.print(f"[bold red]error:[/] {escape(message)}", highlight=False, markup=True, soft_wrap=True)
    raise typer.Exit(code)


@app.callback()
def _options(debug: bool = typer.Option(False, "--debug", help="Show the traceback of an unexpected error")):
    _debug["on"] = debug or os.environ.get("ENVFACTORY_DEBUG") == "1"


def guarded(command):
    """Any error escaping a command becomes one clear message (the traceback with --debug)."""

    @functools.wraps(command)
    def run_guarded(*args, **kwargs):
        try:
            return command(*args, **kwargs)
        except (typer.Exit, typer.Abort, typer.TyperException, KeyboardInterrupt, SystemExit):
            raise
        except Exception as exc:
            if _debug["on"]:
                raise
            if isinstance(exc, SpecError):
                _fail(str(exc))
            text = str(exc).strip().strip("'\"") or "no message"
            _fail(f"{type(exc).__name__}: {text} (run with --debug for the traceback)")

    return run_guarded


def command(*args, **kwargs):
    """app.command with the error guard."""

    def wrap(function):
        return app.command(*args, **kwargs)(guarded(function))

    return wrap


def _check_output(path: Path, suffixes: tuple[str, ...]) -> None:
    """Refuse an output path before any work starts, not after it."""
    if path.suffix.lower() not in suffixes:
        _fail(f"{path}: the file name must end in one of {', '.join(suffixes)}")
    if path.is_dir():
        _fail(f"{path}: is a folder; give a file name")
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        _fail(f"{path}: the folder {parent} does not exist")
    existed = path.exists()
    try:
        with open(path, "ab"):
            pass
    except OSError as exc:
        _fail(f"{path}: cannot write here ({exc.strerror or exc})")
    if not existed:
        path.unlink(missing_ok=True)


def _known(env_id: str) -> None:
    """Refuse an unknown ID with the nearest registered ones, before any work."""
    try:
        registry.record(env_id)
    except KeyError as exc:
        _fail(str(exc).strip("'\""))


def _parse_kwargs(items: List[str] | None) -> dict:
    kwargs = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep:
            _fail(f"--kwarg {item!r}: write name=value")
        try:
            kwargs[name] = yaml.safe_load(value)
        except yaml.YAMLError as exc:
            _fail(f"--kwarg {item!r}: the value is not valid YAML ({str(exc).splitlines()[0]})")
    return kwargs


KWARG_HELP = "gym.make kwarg as name=value, repeatable"
