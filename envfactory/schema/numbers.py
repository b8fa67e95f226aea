"""Number types for specs: finite, and never a bool or a string in disguise.

YAML reads `yes` as true and pydantic would turn that into 1.0; `.nan` and
`.inf` parse as floats that every later comparison quietly mishandles.
"""

from __future__ import annotations

import math
import numbers
from typing import Annotated, Any, Iterator

from pydantic import AfterValidator, BeforeValidator, Field

from envfactory.schema.tree import leaves


def is_number(value: Any) -> bool:
    """A real number as a file or a log gives it: an int or a float, not a bool (YAML's true is no count)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _plain_number(value: Any) -> Any:
    if not is_number(value):
        raise ValueError("Input should be a valid number, not a bool or a string")
    return float(value)


def _finite(value: float) -> float:
    if not math.isfinite(value):
        raise ValueError("Input should be a finite number")
    return value


Real = Annotated[float, BeforeValidator(_plain_number), AfterValidator(_finite)]
Positive = Annotated[Real, Field(gt=0)]
NonNegative = Annotated[Real, Field(ge=0)]

# A tabletop arm's scene fits in a 10 m cube around the world origin: a position or a size
# beyond it is a typo (a misplaced decimal point), never a scene.
SCENE_EXTENT = 10.0
Coordinate = Annotated[Real, Field(ge=-SCENE_EXTENT, le=SCENE_EXTENT)]
Length = Annotated[Real, Field(gt=0, le=SCENE_EXTENT)]
# 2π rounded up in the fourth decimal, so that a full turn written to four places (6.2832) passes as one
TWO_PI = 6.2832
# Angles in radians: more than a full turn either way is never meant.
Angle = Annotated[Real, Field(ge=-TWO_PI, le=TWO_PI)]
# Friction coefficients of real materials stay well below this.
Friction = Annotated[Real, Field(ge=0, le=10.0)]


def non_finite_paths(node: Any) -> Iterator[tuple[str, float]]:
    """Every NaN or infinity anywhere in a plain config tree, with its dotted path."""
    return ((path, value) for path, value in leaves(node) if isinstance(value, float) and not math.isfinite(value))
