"""The `envfactory` command's application object and what every command shares: the error guard that
turns any escaping error into one message, the --specs option of every command naming a robot or ID,
output-path and kwarg checks, the consoles.

Import this module before anything that imports PyBullet (cli/main.py does): it imports PyBullet with
its load-time banner dropped, so no command's output starts with "pybullet build time: ..."."""

from __future__ import annotations

import functools
import importlib
import inspect
import os
import sys
from pathlib import Path
from typing import List, Optional

import typer
import yaml
from rich.console import Console
from rich.markup import escape

from envfactory import registry
from envfactory.cli.lookup import MissingSpecFolder, register_spec_folders, unknown_id
from envfactory.learn.extra import TRAIN_MODULES, MissingExtra, require
from envfactory.schema.errors import SpecError


def _import_without_banner(module: str) -> None:
    """Import a module whose C extension writes a banner to stderr (fd 2) as it loads, with fd 2 on the null
    device for the import alone. Python's own sys.stderr is untouched, and an import error still raises."""
    if module in sys.modules:
        return
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):  # no stderr file descriptor (embedded, closed): import as is
        importlib.import_module(module)
        return
    try:
        with open(os.devnull, "w") as sink:
            os.dup2(sink.fileno(), 2)
            try:
                importlib.import_module(module)
            finally:
                os.dup2(saved, 2)
    finally:
        os.close(saved)


_import_without_banner("pybullet")  # it prints "pybullet build time: ..." once per process, at import

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


def model_file(text: str, choices: str) -> Path:
    """A --policy value that names a model saved by `envfactory train` (`choices`: the words it could be
    instead), checked before anything is made; the [train] extra is needed to load it."""
    path = Path(text)
    if path.suffix.lower() != ".zip":
        _fail(f"--policy {text!r}: use {choices} or a model file (.zip) saved by `envfactory train`")
    if not path.is_file():
        _fail(f"--policy {path}: no such file")
    try:
        require(TRAIN_MODULES, "--policy MODEL.zip")
    except MissingExtra as exc:
        _fail(str(exc))
    return path


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


# A command whose signature has one of these names a robot or an env ID: it takes --specs.
NAMING_PARAMETERS = ("env_id", "robot")
SPECS_HELP = ("A spec folder of your own (robots/, tasks/, specs/) whose IDs and robots this command may name, "
              "repeatable; `envfactory register PATH` records one for every later command")


def with_spec_folders(command):
    """The command with a --specs option: its folders are registered before the command runs."""

    signature = inspect.signature(command, eval_str=True)
    option = inspect.Parameter("specs", inspect.Parameter.KEYWORD_ONLY, annotation=Optional[List[Path]],
                               default=typer.Option(None, "--specs", help=SPECS_HELP, show_default=False))

    @functools.wraps(command)
    def run_with_folders(*args, specs: Optional[List[Path]] = None, **kwargs):
        try:
            problems = register_spec_folders(list(specs or []))
        except MissingSpecFolder as exc:
            _fail(str(exc))
        for problem in problems:  # a broken family stays out; the rest of the folder serves the command
            errors.print(f"warning: family skipped: {registry.one_line(problem)}", highlight=False, markup=False,
                         soft_wrap=True)
        return command(*args, **kwargs)

    run_with_folders.__signature__ = signature.replace(parameters=[*signature.parameters.values(), option])
    # a copy: functools.wraps shares the command's own annotations dict, which must not change
    run_with_folders.__annotations__ = {**command.__annotations__, "specs": Optional[List[Path]]}
    return run_with_folders


def command(*args, **kwargs):
    """app.command with the error guard; a command naming a robot or ID (NAMING_PARAMETERS) also takes --specs."""

    def wrap(function):
        names = inspect.signature(function).parameters
        if any(name in names for name in NAMING_PARAMETERS):
            function = with_spec_folders(function)
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
    """Refuse an unknown ID with the nearest registered one and how to add a folder, before any work."""
    problem = unknown_id(env_id)
    if problem is not None:
        _fail(problem)


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
