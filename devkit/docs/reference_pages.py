"""The reference pages: reference/cli.md (the typer app's commands), reference/kwargs.md (the gym.make kwargs
of the shipped specs) and reference/terms.md (the term library, as `envfactory terms` lists it)."""

from __future__ import annotations

import types
import typing

import typer.core
import typer.main
from pydantic import BaseModel, create_model
from typer import Context

from devkit.docs import mdtext as md
from devkit.docs.env_pages import Family
from devkit.docs.kwarg_meanings import MEANINGS
from envfactory import factory
from envfactory.cli.app import app
from envfactory.schema.models import ComposedSpec
from envfactory.views import term_catalog as catalog
from envfactory.views.describe import kwarg_paths, value_at

# ------------------------------------------------------------------ cli.md


def cli_page() -> str:
    group = typer.main.get_command(app)
    root = Context(group, info_name="envfactory")
    names = group.list_commands(root)
    blocks = [
        md.prose(group.help or ""),
        "```\nenvfactory " + " ".join(group.collect_usage_pieces(root)) + "\n```",
        "Options before the command:\n\n" + _options_table(group, root),
        (
            "Every command also takes `--help`. A command that fails prints one line, `error: …`, and exits 1 "
            "(`--debug` shows the traceback instead)."
        ),
        md.grid(
            ["Command", "What it does"],
            [
                (f"[{name}](#{md.anchor('envfactory ' + name)})", md.prose(_first_line(group.commands[name].help)))
                for name in names
            ],
        ),
    ]
    for name in names:
        command = group.commands[name]
        context = Context(command, info_name=name, parent=root)
        blocks += [
            f"## envfactory {name}",
            md.prose(command.help or ""),
            f"```\nenvfactory {name} " + " ".join(command.collect_usage_pieces(context)) + "\n```",
        ]
        arguments = [p for p in command.get_params(context) if isinstance(p, typer.core.TyperArgument)]
        if arguments:
            blocks.append("**Arguments**\n\n" + _params_table(arguments, context, "Argument"))
        blocks.append("**Options**\n\n" + _options_table(command, context))
    return md.page("Command line: envfactory", *blocks)


def _first_line(text: str | None) -> str:
    return (text or "").strip().split("\n\n")[0]


def _params_table(params, context: Context, heading: str) -> str:
    rows = []
    for param in params:
        names, help_text = param.get_help_record(context)
        # a help escapes a bracket for Rich, which prints it (\[ray] for [ray]); the page shows the bracket
        rows.append((md.code(names), md.prose(help_text.replace("\\[", "["))))
    return md.grid([heading, "Help (default, range)"], rows)


def _options_table(command, context: Context) -> str:
    options = [p for p in command.get_params(context) if isinstance(p, typer.core.TyperOption) and p.name != "help"]
    return _params_table(options, context, "Option") if options else "None besides `--help`."


# ------------------------------------------------------------------ kwargs.md

SECTIONS = [  # in page order: a kwarg is listed in the section with the longest prefix of its spec path
    ("Env, action, observation and simulation", ("env.", "sim.")),
    ("Task", ("task.",)),
    ("Real robot (Real IDs, over rosbridge)", ("env.real.", "robot.ros.")),
]


def section_of(path: str) -> str:
    matches = [(len(prefix), title) for title, prefixes in SECTIONS for prefix in prefixes if path.startswith(prefix)]
    if not matches:
        raise ValueError(f"no section of the kwargs page covers the spec path {path!r}: add one to SECTIONS")
    return max(matches)[1]


def kwargs_page(families: list[Family]) -> str:
    accepted: dict[str, dict[str, list]] = {}  # kwarg -> spec path -> the shipped IDs' values
    tasks: dict[str, set[str]] = {}
    for family in families:
        for env_id in family.ids:
            spec = factory.blueprint(env_id).spec
            for name, path in kwarg_paths(spec).items():
                if path.startswith("robot.ros.") and spec.robot.ros is None:
                    continue  # a simulation-only robot has no topics to list
                accepted.setdefault(name, {}).setdefault(path, []).append(value_at(spec, path))
                tasks.setdefault(name, set()).add(spec.task.label)
    _check_accepted(accepted)
    all_tasks = set().union(*tasks.values())
    blocks = [
        (
            "A gym.make kwarg is an alias of one spec path: `gym.make(ID, name=value)` sets that path before the spec "
            "is validated, so a bad value fails with the path and the kwarg named. The aliases are declared in the "
            "spec YAML: `specs/_defaults.yaml` (every family) and each task file's `kwargs:` block. The command line "
            "takes them as `-k name=value`, and `envfactory describe ID name=value` as overrides. An unknown kwarg "
            "fails and lists the valid ones."
        ),
        (
            "*Type = schema default* is the spec field's type, its default when a spec leaves it out, and its limits. "
            "*Shipped IDs* is the value the shipped IDs take (registered kwargs included); the env pages give each "
            "ID's."
        ),
    ]
    for title, _ in SECTIONS:
        rows = []
        for name in sorted(accepted):
            ((path, values),) = accepted[name].items()
            if section_of(path) != title:
                continue
            where = "" if tasks[name] == all_tasks else f" ({', '.join(sorted(tasks[name]))} only)"
            rows.append(
                (
                    f'<a id="{md.kwarg_anchor(name)}"></a>{md.code(name)}',
                    md.code(path),
                    md.escape(field_doc(path)),
                    _values(values),
                    md.prose(MEANINGS[name]) + md.escape(where),
                )
            )
        blocks += [
            f"## {title}",
            md.grid(["Kwarg", "Spec path", "Type = schema default", "Shipped IDs", "Meaning"], rows),
        ]
    return md.page("gym.make kwargs", *blocks)


def _check_accepted(accepted: dict) -> None:
    clashes = [f"{name} ({', '.join(paths)})" for name, paths in accepted.items() if len(paths) > 1]
    if clashes:
        raise ValueError(f"kwargs with different spec paths in different shipped families: {'; '.join(clashes)}")
    missing = sorted(set(accepted) - set(MEANINGS))
    stale = sorted(set(MEANINGS) - set(accepted))
    if missing or stale:
        raise ValueError(
            "devkit/docs/kwarg_meanings.py is out of step with the specs: "
            + "; ".join(
                filter(
                    None,
                    [
                        missing and f"no meaning for {', '.join(missing)}",
                        stale and f"no shipped spec declares {', '.join(stale)}",
                    ],
                )
            )
        )


def _values(values: list) -> str:
    distinct = list(dict.fromkeys(map(repr, values)))
    if len(distinct) == 1:
        return md.code(distinct[0])
    if len(distinct) <= 3:
        return " or ".join(map(md.code, distinct)) + " (by ID)"
    return f"{len(distinct)} values, by ID (see the env pages)"


def field_doc(dotted: str) -> str:
    """`type = default (limits)` of the schema field at a spec path, as `envfactory terms` writes params."""
    model: typing.Any = ComposedSpec
    field = None
    for part in dotted.split("."):
        if isinstance(model, type) and issubclass(model, BaseModel):
            field = model.model_fields[part]
            model = field.annotation
        else:  # a mapping of names to models, e.g. robot.ros.object_poses.<object>
            model = typing.get_args(model)[-1]
            field = None
        if typing.get_origin(model) in (typing.Union, types.UnionType):  # an optional block: its model
            options = [a for a in typing.get_args(model) if a is not type(None)]
            model = options[0] if len(options) == 1 else model
    if field is None:
        raise ValueError(f"spec path {dotted!r} ends in a mapping, not a field")
    name = dotted.rsplit(".", 1)[1]
    documented = catalog.params_doc(create_model("Kwarg", **{name: (field.annotation, field)}))
    return documented.partition(": ")[2]


# ------------------------------------------------------------------ terms.md


def terms_page() -> str:
    blocks = [
        (
            "Every observation, reward, termination, image, event and sensing term and every scripted expert "
            "that ships with envfactory, with its params (`name: type = default (limits)`), size and unit: the tables "
            "`envfactory terms` prints. A spec names a term by its name; `envfactory terms MODULE` lists a "
            "module's own terms beside these."
        )
    ]
    for title, columns, rows in catalog.TABLES:
        blocks += [
            f"## {md.escape(title)}",
            md.grid(columns, ([md.code(name), *map(md.prose, rest)] for name, *rest in rows())),
        ]
    return md.page("Terms and experts", *blocks)
