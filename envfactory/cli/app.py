"""The `envfactory` command: the application, built from the list of its commands, and its entry point.

Every command is named here, in the order `envfactory --help` lists them; each lives in the module of its
subject. Bad input never ends in a traceback: every command reports the error in one message and exits 1
(`--debug` shows the traceback instead).
"""

from __future__ import annotations

import sys

import typer

from envfactory.cli import evaluate, learn, run, safety, specs, twin
from envfactory.cli.common import prepared, set_debug

COMMANDS = [
    evaluate.evaluate,  # a policy over IDs and seeds (Ray with --workers)
    learn.train,
    learn.collect,  # learning and datasets
    safety.collision_pairs,
    safety.safety_view,  # the safety geometry
    specs.validate,
    specs.list_ids,
    specs.describe,
    specs.register,
    specs.unregister,
    specs.terms,  # specs
    run.run,
    run.sensing_spec,  # the main job, and what it measures on a real path
    twin.twin,  # the digital twin
]

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="A config-driven factory of Gymnasium environments for robot arms.",
)


@app.callback()
def _options(debug: bool = typer.Option(False, "--debug", help="Show the traceback of an unexpected error")):
    set_debug(debug)


for _function in COMMANDS:
    _name, _options_of = _function.command_options
    app.command(_name, **_options_of)(prepared(_function))


def main() -> None:  # pragma: no cover
    sys.exit(app())


if __name__ == "__main__":  # pragma: no cover
    main()
