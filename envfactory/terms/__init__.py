"""The term library. Importing it registers every built-in term."""

from envfactory.terms import grasp, objects, observations, rewards  # noqa: F401  (registration)
from envfactory.terms.library import OBSERVATIONS, REWARDS, TERMINATIONS, Layout

__all__ = ["OBSERVATIONS", "REWARDS", "TERMINATIONS", "Layout"]
