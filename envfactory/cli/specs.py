"""The commands about spec folders and IDs: validate, list, describe, register, unregister, terms."""

from __future__ import annotations

from pathlib import Path
from typing import List

import typer
from rich.table import Table

from envfactory import factory
from envfactory.cli.common import KWARG_HELP, command, console, errors, fail, known_id, make_kwargs, override_option
from envfactory.compiler.scene_checks import height_summary
from envfactory.registration import registry, user_config
from envfactory.registration.user_config import config_file
from envfactory.schema.compose import load_env_spec
from envfactory.schema.errors import SpecError
from envfactory.terms import plugins
from envfactory.views import term_catalog
from envfactory.views.describe import id_summary, render_description


@command()
def validate(paths: List[Path] = typer.Argument(None, help="Spec folders or family files; default: every spec.")):
    """Compose and compile every ID of the given specs as make would; report errors with file:line."""

    missing = [path for path in paths or [] if not path.exists()]
    if missing:
        fail("; ".join(f"{path}: no such file or folder{registry.nearest_entry(path)}" for path in missing))
    folders = paths or [registry.builtin_root(), *(folder for folder, _ in registry.user_folders())]
    targets, unread, notes = _validate_targets(folders, given=bool(paths))
    failures, checked = len(unread), 0
    for message in unread:
        errors.print(message, highlight=False, markup=False, soft_wrap=True)
    pending: dict = {}
    for path in targets:
        try:
            records = registry.scan_family(path, registry.search_roots(registry.folder_of(path)))
            clashes = [p for p in (registry.clash(r, pending) for r in records) if p is not None]
            if clashes:
                raise SpecError(clashes, path.stem)
            factory.check_family(records)
            pending.update({r.env_id: r for r in records})
            checked += len(records)
            if records:
                spec = load_env_spec(records[0].family, (), dict(records[0].kwargs), env_id=records[0].env_id).spec
                console.print(
                    f"{path.stem}: {len(records)} ID(s) valid. {height_summary(spec)}", highlight=False, soft_wrap=True
                )
        except SpecError as exc:
            failures += 1
            errors.print(str(exc), highlight=False, markup=False, soft_wrap=True)
    for note in notes:
        console.print(note, highlight=False, soft_wrap=True)
    if failures:
        fail(f"{failures} spec file(s) invalid, {checked} ID(s) valid")
    console.print(f"{checked} ID(s) in {len(targets)} spec file(s): valid")


def _validate_targets(folders: list[Path], given: bool) -> tuple[list[Path], list[str], list[str]]:
    """The family files to validate; the messages of folders whose families are not read (refused: a family that
    is never registered must not pass unnoticed); notes on what `register` will make of a path."""
    targets, unread, notes = [], [], []
    for path in folders:
        if path.is_dir():
            listing = registry.list_folder(path)
            targets += listing.families
            unread += [f"{file}: {why}" for file, why in registry.unread_files(listing)]
        elif path.exists() or not given:
            targets.append(path)
            if given:
                notes.append(
                    f"note: {path} is a family file; `envfactory register` and {registry.SPEC_PATH_VARIABLE} "
                    f"take its spec folder, {registry.folder_of(path)}"
                )
    return targets, unread, notes


@command("list")
def list_ids(sources: bool = typer.Option(False, "--sources", help="Where the IDs come from: each spec folder")):
    """Every registered ID with its robot, task, backend and sizes."""

    if sources:
        _list_sources()
        return
    table = Table("ID", "Robot", "Task", "Backend", "Obs", "Action")
    for env_id, record in sorted(registry.records().items()):
        try:
            compiled = factory.blueprint(env_id)
        except SpecError as exc:
            table.add_row(env_id, "?", "?", record.backend, "invalid", str(exc.problems[0]) if exc.problems else "")
            continue
        table.add_row(env_id, *id_summary(compiled))
    console.print(table)


def _list_sources() -> None:
    by_folder: dict[Path, list[str]] = {}
    for env_id, record in registry.records().items():
        by_folder.setdefault(registry.folder_of(record.family.path).resolve(), []).append(env_id)
    table = Table("Source", "Folder", "IDs", title=f"spec folders (config file: {config_file()})")
    folders = [(registry.builtin_root(), registry.BUILTIN_SOURCE), *registry.user_folders()]
    for folder, source in folders:
        ids = sorted(by_folder.get(folder.expanduser().resolve(), []))
        state = f"{len(ids)}" if folder.is_dir() else "0 (missing folder)"
        table.add_row(
            source, str(folder), state + (f": {', '.join(ids[:4])}{', …' if len(ids) > 4 else ''}" if ids else "")
        )
    console.print(table)


@command()
def describe(
    env_id: str,
    overrides: List[str] = typer.Argument(None, help="Hydra overrides, e.g. env.action.ee=true (or -o)"),
    override: List[str] = override_option(),
    kwarg: List[str] = typer.Option(None, "--kwarg", "-k", help=KWARG_HELP),
):
    """The observation index table, action table, reward terms and goal box of an ID."""

    known_id(env_id)
    kwargs = make_kwargs(kwarg, [*(overrides or ()), *(override or ())])
    render_description(factory.blueprint(env_id, **kwargs), console)


@command()
def register(
    paths: List[Path] = typer.Argument(..., help="Folders of user specs"),
    save: bool = typer.Option(
        True,
        "--save/--no-save",
        help="Record the folders in the user config file, so later processes register them too",
    ),
):
    """Validate user spec folders, smoke-build each simulated ID (reset plus one step), and record them."""

    failed = False
    for path in paths:
        if not path.is_dir():
            errors.print(f"{path}: {registry.not_a_folder(path)}", highlight=False, markup=False)
            failed = True
            continue
        factory.unregister_folder(path)  # registered lazily at import: validate it in full now
        added, problems = factory.register_specs(path)
        for problem in problems:
            failed = True
            errors.print(str(problem), highlight=False, markup=False, soft_wrap=True)
        failed |= not _smoke_build(added)
        if not added and not problems:
            errors.print(f"{path}: no family files (*.yaml) with IDs", highlight=False, markup=False)
            failed = True
        if save and added and not problems:
            new = user_config.add_folder(path)
            console.print(
                f"{'recorded' if new else 'already recorded'} {path.resolve()} in {user_config.config_file()}"
            )
        elif save and problems:
            errors.print(
                f"{path}: not recorded in {user_config.config_file()}: fix the errors above and register again",
                highlight=False,
                markup=False,
            )
    if failed:
        raise typer.Exit(1)


def _smoke_build(env_ids: list[str]) -> bool:
    import gymnasium as gym

    ok = True
    for env_id in env_ids:
        backend = registry.records()[env_id].backend
        if backend != "sim":
            console.print(f"registered {env_id} (backend {backend}: not smoke-built, it would need the robot)")
            continue
        try:
            env = gym.make(env_id)
            try:
                env.reset(seed=0)
                env.step(env.action_space.sample())
            finally:
                env.close()
            console.print(f"registered {env_id}: reset and step ok")
        except Exception as exc:  # report, keep going with the other IDs
            ok = False
            errors.print(f"{env_id}: smoke build failed: {exc}", highlight=False, markup=False)
    return ok


@command()
def unregister(paths: List[Path] = typer.Argument(..., help="Folders recorded by `envfactory register`")):
    """Forget recorded spec folders: later processes no longer register their IDs."""

    recorded = user_config.registered_folders()
    for path in paths:
        if user_config.remove_folder(path):
            console.print(f"removed {path.resolve()} from {user_config.config_file()}")
        else:
            known = ", ".join(map(str, recorded)) or "none"
            fail(f"{path.resolve()} is not recorded in {user_config.config_file()} (recorded: {known})")


@command()
def terms(
    modules: List[str] = typer.Argument(
        None, help="Term modules to import first (as a spec's `terms:` list names them, relative to the current folder)"
    ),
):
    """Every observation, reward, termination, image, event and sensing term and every expert, with params, size
    and unit."""

    plugins.load_entry_points()
    for name in modules or []:
        try:
            plugins.import_module(name, Path.cwd())
        except Exception as exc:
            fail(f"cannot import term module {name!r}: {type(exc).__name__}: {exc}")
    for title, columns, rows in term_catalog.TABLES:
        table = Table(title=title, title_justify="left")
        for index, column in enumerate(columns):
            table.add_column(column, no_wrap=index == 0)  # a term's name is what a spec types: never cut
        for row in rows():
            table.add_row(*row)
        console.print(table)
