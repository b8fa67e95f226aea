"""The `envfactory` command: app.py builds it from the list of its commands, one module per subject.

Importing any part of it first imports PyBullet with its load-time banner dropped, so no command's output
starts with "pybullet build time: ...", whatever a command module imports and in whichever order."""

import importlib
import os
import sys


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
