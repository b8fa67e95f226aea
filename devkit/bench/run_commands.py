"""How a run folder was made, as commands a reader can type again: `envfactory train` as the run recorded it
(model.json), its demonstration dataset named by the `envfactory collect` command that makes it, never by where
it lay on the machine that trained."""

from __future__ import annotations

import json
import re
import shlex


def train_commands(record: dict) -> list[str]:
    """The collect command of the run's dataset (if it learned from one), then its train command."""
    train = re.sub(r"--demos \S+", "--demos DATASET", record["command"])
    demos = record.get("demos")
    if not demos:
        return [train]
    # quoted for the shell: a value may hold brackets and quotes (a list of overrides)
    kwargs = " ".join(
        f"-k {shlex.quote(f'{name}={json.dumps(value)}')}" for name, value in record["env_kwargs"].items()
    )
    noise = f" --action-noise {demos['action_noise']:g}" if demos.get("action_noise") else ""
    collect = f"envfactory collect {record['env_id']} {kwargs} -n {demos.get('episodes')}{noise}   # DATASET"
    return [collect, train]
