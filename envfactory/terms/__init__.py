"""The term library. Importing it registers every built-in term."""

from envfactory.terms import (  # noqa: F401  (registration)
    events,
    fixtures,
    grasp,
    images,
    objects,
    observations,
    rewards,
    sensing,
)
from envfactory.terms.library import EVENTS, IMAGES, OBSERVATIONS, REWARDS, SENSING, TERMINATIONS, TermContext

__all__ = ["EVENTS", "IMAGES", "OBSERVATIONS", "REWARDS", "SENSING", "TERMINATIONS", "TermContext"]
