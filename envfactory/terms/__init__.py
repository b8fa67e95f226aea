"""The term library. Importing it registers every built-in term."""

from envfactory.terms import events, grasp, images, objects, observations, rewards, sensing  # noqa: F401  (registration)
from envfactory.terms.library import EVENTS, IMAGES, OBSERVATIONS, REWARDS, SENSING, TERMINATIONS, TermContext

__all__ = ["EVENTS", "IMAGES", "OBSERVATIONS", "REWARDS", "SENSING", "TERMINATIONS", "TermContext"]
