"""Backends by name. Built-ins load lazily; others join through the
`envfactory.backends` entry-point group."""

from __future__ import annotations

import importlib
from importlib.metadata import entry_points

from envfactory.backends.base import Backend, BackendError, JointReading, ObjectReading

BUILTIN = {
    "pybullet": "envfactory.backends.pybullet:PyBulletBackend",
    "mujoco": "envfactory.backends.mujoco:MujocoBackend",
    "rosbridge": "envfactory.backends.rosbridge:RosbridgeBackend",
}


def available() -> list[str]:
    return sorted({*BUILTIN, *(ep.name for ep in entry_points(group="envfactory.backends"))})


def backend_factory(name: str):
    target = BUILTIN.get(name)
    if target is None:
        found = [ep for ep in entry_points(group="envfactory.backends") if ep.name == name]
        if not found:
            raise ValueError(f"unknown backend {name!r} (available: {', '.join(available())})")
        return found[0].load()
    module, _, attribute = target.partition(":")
    return getattr(importlib.import_module(module), attribute)


__all__ = ["Backend", "BackendError", "JointReading", "ObjectReading", "available", "backend_factory"]
