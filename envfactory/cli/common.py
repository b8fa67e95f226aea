"""What every `envfactory` command shares: the error guard that turns any escaping error into one message,
the --specs option of every command naming a robot or ID, output-path and kwarg checks, the consoles, and
the `command` mark that cli/app.py reads when it builds the application from its list of commands."""

from __future__ import annotations

import functools
import inspect
import os
import sys
from pathlib import Path
from typing import List, Optional

import typer
import yaml
from rich.console import Console
from rich.markup import escape

from envfactory import factory
from envfactory.cli.lookup import MissingSpecFolder, register_spec_folders, unknown_id
from envfactory.learn.extra import TRAIN_MODULES, MissingExtra, require
from envfactory.registration import registry
from envfactory.schema.errors import SpecError

# Tables stay whole when the output is piped or captured.
_WIDTH = None if sys.stdout.isatty() else 140
console = Console(width=_WIDTH)
errors = Console(stderr=True, width=_WIDTH)
_debug = {"on": False}


def fail(message: str, code: int = 1) -> None:
    # the message is plain text: brackets in it ([train], list values) are not markup
    errors.print(f"[bold red]error:[/] {escape(message)}", highlight=False, markup=True, soft_wrap=True)
    raise typer.Exit(code)


def model_file(text: str, choices: str) -> Path:
    """A --policy value that names a model saved by `envfactory train` (`choices`: the words it could be
    instead), checked before anything is made; the [train] extra is needed to load it."""
    path = Path(text)
    if path.suffix.lower() != ".zip":
        fail(f"--policy {text!r}: use {choices} or a model file (.zip) saved by `envfactory train`")
    if not path.is_file():
        fail(f"--policy {path}: no such file")
    try:
        require(TRAIN_MODULES, "--policy MODEL.zip")
    except MissingExtra as exc:
        fail(str(exc))
    return path


def set_debug(debug: bool) -> None:
    """Whether an unexpected error shows its traceback (--debug, or ENVFACTORY_DEBUG=1)."""
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
                fail(str(exc))
            text = str(exc).strip().strip("'\"") or "no message"
            fail(f"{type(exc).__name__}: {text} (run with --debug for the traceback)")

    return run_guarded


# A command whose signature has one of these names a robot or an env ID: it takes --specs.
NAMING_PARAMETERS = ("env_id", "robot")
SPECS_HELP = (
    "A spec folder of your own (robots/, tasks/, specs/) whose IDs and robots this command may name, "
    "repeatable; `envfactory register PATH` records one for every later command"
)


def with_spec_folders(command):
    """The command with a --specs option: its folders are registered before the command runs."""

    signature = inspect.signature(command, eval_str=True)
    option = inspect.Parameter(
        "specs",
        inspect.Parameter.KEYWORD_ONLY,
        annotation=Optional[List[Path]],
        default=typer.Option(None, "--specs", help=SPECS_HELP, show_default=False),
    )

    @functools.wraps(command)
    def run_with_folders(*args, specs: Optional[List[Path]] = None, **kwargs):
        try:
            problems = register_spec_folders(list(specs or []))
        except MissingSpecFolder as exc:
            fail(str(exc))
        for problem in problems:  # a broken family stays out; the rest of the folder serves the command
            errors.print(
                f"warning: family skipped: {registry.one_line(problem)}", highlight=False, markup=False, soft_wrap=True
            )
        return command(*args, **kwargs)

    run_with_folders.__signature__ = signature.replace(parameters=[*signature.parameters.values(), option])
    # a copy: functools.wraps shares the command's own annotations dict, which must not change
    run_with_folders.__annotations__ = {**command.__annotations__, "specs": Optional[List[Path]]}
    return run_with_folders


def command(name: str | None = None, **options):
    """Mark a function as a command: its name (the function's, dashed, by default) and typer's options for it.
    cli/app.py lists the commands and adds each with `prepared`."""

    def mark(function):
        function.command_options = (name, options)
        return function

    return mark


def prepared(function):
    """A command function with the error guard; one naming a robot or ID (NAMING_PARAMETERS) also takes
    --specs."""
    names = inspect.signature(function).parameters
    if any(name in names for name in NAMING_PARAMETERS):
        function = with_spec_folders(function)
    return guarded(function)


def check_output(path: Path, suffixes: tuple[str, ...]) -> None:
    """Refuse an output path before any work starts, not after it."""
    if path.suffix.lower() not in suffixes:
        fail(f"{path}: the file name must end in one of {', '.join(suffixes)}")
    if path.is_dir():
        fail(f"{path}: is a folder; give a file name")
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        fail(f"{path}: the folder {parent} does not exist")
    existed = path.exists()
    try:
        with open(path, "ab"):
            pass
    except OSError as exc:
        fail(f"{path}: cannot write here ({exc.strerror or exc})")
    if not existed:
        path.unlink(missing_ok=True)


def known_id(env_id: str) -> None:
    """Refuse an unknown ID with the nearest registered one and how to add a folder, before any work."""
    problem = unknown_id(env_id)
    if problem is not None:
        fail(problem)


OVERRIDE_HELP = "Spec override as KEY=VALUE (Hydra syntax), repeatable; -k 'overrides=[...]' is the same"


def override_option():
    """-o/--override: the one spelling of a spec override on every command that makes an env."""
    return typer.Option(None, "--override", "-o", help=OVERRIDE_HELP)


def joined_overrides(kwargs: dict, given: List[str] | None) -> list[str]:
    """The command's overrides (-o) and those given as `-k overrides=[...]`, taken out of `kwargs`, in one list:
    both spellings reach the spec the same way."""
    for item in given or []:
        if "=" not in item and not item.startswith("~"):
            fail(
                f"-o {item!r}: an override is KEY=VALUE (e.g. -o env.action.ee=true); a run folder or an "
                f"output file is given with --out"
            )
    extra = kwargs.pop("overrides", None)
    if extra is None:
        return list(given or [])
    extra = [extra] if isinstance(extra, str) else extra
    if not (isinstance(extra, list) and all(isinstance(item, str) for item in extra)):
        fail(f"-k overrides={extra!r}: write a list of KEY=VALUE overrides, e.g. -k 'overrides=[env.action.ee=true]'")
    return list(given or []) + extra


def make_kwargs(kwarg: List[str] | None, override: List[str] | None, trained: dict | None = None) -> dict:
    """gym.make's kwargs from a command's -k and -o, over the kwargs a model was trained with (`trained`): a -k
    replaces a trained kwarg, and overrides of either spelling follow the trained ones (a later one wins), all as
    gym.make's one `overrides` kwarg (which a trained model records like any other kwarg)."""
    kwargs = parse_kwargs(kwarg)
    overrides = joined_overrides(kwargs, override)
    base = dict(trained or {})
    every = joined_overrides(base, None) + overrides
    merged = {**base, **kwargs}
    return {**merged, "overrides": every} if every else merged


def parse_kwargs(items: List[str] | None) -> dict:
    kwargs = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep:
            fail(f"--kwarg {item!r}: write name=value")
        try:
            kwargs[name] = yaml.safe_load(value)
        except yaml.YAMLError as exc:
            fail(f"--kwarg {item!r}: the value is not valid YAML ({str(exc).splitlines()[0]})")
    return kwargs


KWARG_HELP = "gym.make kwarg as name=value, repeatable"

ALLOW_REAL_HELP = "Let a Real ID move the arm (the motion gate); clear the workspace first"


def allow_real_option():
    return typer.Option(False, "--allow-real-robot-motion", help=ALLOW_REAL_HELP)


def is_real(env_id: str) -> bool:
    return registry.records()[env_id].backend == "rosbridge"


def real_arm_kwargs(env_id: str, trained_kwargs: dict) -> dict:
    """The kwargs a model was trained with, as `env_id` takes them: on a Real ID the model runs as it is, without
    what only a simulator has (its engine, fidelity, randomization), and the dropped ones are printed."""
    if not is_real(env_id):
        return trained_kwargs
    dropped = factory.simulation_only_kwargs(env_id, trained_kwargs)
    if dropped:
        console.print(
            f"{env_id} is a real arm: the model's simulation-only kwargs are left out: "
            f"{', '.join(f'{name}={trained_kwargs[name]!r}' for name in dropped)}",
            highlight=False,
        )
    return {name: value for name, value in trained_kwargs.items() if name not in dropped}
