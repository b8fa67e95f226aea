"""The scripted expert's working points for a spec (each expert names its own: experts/points.py), which the
workspace checks (`scene_checks`) and the reach and safety checks (`robot_checks`) judge."""

from __future__ import annotations

from envfactory.experts import EXPERTS
from envfactory.experts.points import ExpertPoint
from envfactory.schema.models import ComposedSpec


def expert_points(spec: ComposedSpec) -> list[ExpertPoint]:
    """The expert's working points, or [] without an expert (or with one whose params do not validate: the
    compiler reports those)."""
    ref = spec.task.expert
    if ref is None or ref.policy not in EXPERTS:
        return []
    expert = EXPERTS[ref.policy]
    try:
        params = expert.Params.model_validate(ref.params)
    except ValueError:
        return []
    return expert.working_points(params, spec)
