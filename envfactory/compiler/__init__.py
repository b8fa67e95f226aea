"""The compiler: a validated spec becomes an immutable Blueprint, or every problem found is raised at once."""

from envfactory.compiler.blueprint import (
    ActionLayout,
    ActionRow,
    Blueprint,
    ImageSlot,
    ObservationSlot,
    TerminationSlot,
    WeightedTerm,
)
from envfactory.compiler.compile import compile_blueprint

__all__ = [
    "ActionLayout",
    "ActionRow",
    "Blueprint",
    "ImageSlot",
    "ObservationSlot",
    "TerminationSlot",
    "WeightedTerm",
    "compile_blueprint",
]
