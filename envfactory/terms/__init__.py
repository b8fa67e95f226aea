"""The term library. Importing it registers every built-in term."""

from envfactory.terms import grasp, images, objects, observations, rewards  # noqa: F401  (registration)
from envfactory.terms.library import IMAGES, OBSERVATIONS, REWARDS, TERMINATIONS, Layout

__all__ = ["IMAGES", "OBSERVATIONS", "REWARDS", "TERMINATIONS", "Layout"]
