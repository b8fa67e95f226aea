"""The URDF's masses and inertias judged by the rules both engines apply, at validate: MuJoCo refuses at make a
body whose principal moments break the triangle inequality (no rigid body has them) or whose inertia is not
positive semi-definite, and PyBullet runs such a body with dynamics that mean nothing. Each link is named with
its line in the URDF."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import numpy as np

# relative slack, as the engines allow for moments rounded in a URDF
TOLERANCE = 1e-6
INERTIA_KEYS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")


def inertia_problems(urdf: Path) -> list[str]:
    """One line per link whose <inertial> no rigid body can have, naming the file, line, link and numbers."""
    text = urdf.read_text()
    lines = text.splitlines()
    problems = []
    try:
        root = ElementTree.fromstring(text)
    except ElementTree.ParseError:  # undeclared prefixes the assembly strips: it has judged the file already
        return []
    for link in root.iter("link"):
        inertial = link.find("inertial")
        if inertial is None:
            continue
        name = link.get("name", "?")
        where = f"{urdf}:{_line_of(lines, name)}: link {name!r}"
        mass_tag, inertia_tag = inertial.find("mass"), inertial.find("inertia")
        try:
            mass = float(mass_tag.get("value")) if mass_tag is not None else 0.0
            values = [float(inertia_tag.get(key, 0.0)) if inertia_tag is not None else 0.0 for key in INERTIA_KEYS]
        except (TypeError, ValueError):
            problems.append(f"{where}: a mass or inertia value is not a number")
            continue
        if not (math.isfinite(mass) and mass >= 0) or not all(math.isfinite(value) for value in values):
            problems.append(f"{where}: mass {mass:g} kg or an inertia value is negative or not finite")
            continue
        problem = _moments_problem(values)
        if problem:
            problems.append(f"{where}: {problem}")
    return problems


def _moments_problem(values: list[float]) -> str:
    ixx, ixy, ixz, iyy, iyz, izz = values
    moments = np.sort(np.linalg.eigvalsh(np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])))
    scale = max(float(np.max(np.abs(moments))), 1e-12)
    shown = ", ".join(f"{moment:.4g}" for moment in moments)
    if moments[0] < -TOLERANCE * scale:
        return f"principal moments {shown} kg·m²: a negative one (the inertia is not positive semi-definite)"
    if moments[0] + moments[1] < moments[2] - TOLERANCE * scale:
        return (
            f"principal moments {shown} kg·m² break the triangle inequality ({moments[0]:.4g} + {moments[1]:.4g} < "
            f"{moments[2]:.4g}): no rigid body has them; MuJoCo refuses the body, PyBullet's dynamics go wrong"
        )
    return ""


def _line_of(lines: list[str], link: str) -> int:
    return next((number for number, line in enumerate(lines, 1) if f'<link name="{link}"' in line), 1)
