import re

import typer
from typer.testing import CliRunner

from envfactory.cli.app import app

BRACKETED = re.compile(r"\[[a-z][a-z0-9_,-]*\]")


def test_every_bracketed_word_in_a_help_text_is_printed():
    """Rich reads "[ray]" as a markup tag and drops it: "Needs the  extra". Every bracketed word that a
    command's or option's help holds must reach the printed --help."""
    group = typer.main.get_command(app)
    missing = []
    for name, command in group.commands.items():
        texts = [command.help or ""] + [getattr(param, "help", None) or "" for param in command.params]
        words = {word for text in texts for word in BRACKETED.findall(text)}
        if not words:
            continue
        printed = " ".join(CliRunner().invoke(app, [name, "--help"], terminal_width=400).output.split())
        missing += [f"{name}: {word}" for word in sorted(words) if word not in printed]
    assert not missing, missing
