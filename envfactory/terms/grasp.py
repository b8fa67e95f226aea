"""Whether the gripper holds an object: near the EE and the gripper closed past its threshold.

The direction of "closed" comes from the robot's declared open and closed
values, so a knuckle that grows as it closes and fingers that shrink as
they close are judged by the same code.
"""

from __future__ import annotations

from dataclasses import dataclass

from pydantic import Field

from envfactory.geometry.vectors import length
from envfactory.schema.models import GripperSpec
from envfactory.terms.library import Description, TermParams, constant_bounds, fixed, observation_term, reward_term
from envfactory.terms.objects import bind_object


class GraspParams(TermParams):
    object: str
    distance: float = Field(default=0.05, gt=0, le=0.5)  # grasp_dist_thresh: farthest EE-to-object distance
    threshold: float | None = None  # a gripper joint value; the robot's gripper.grasp_threshold if unset


@dataclass(frozen=True)
class GraspTest:
    object: str
    distance: float
    threshold: float
    closure: float  # the threshold as a closure fraction, 0 open .. 1 closed
    gripper: GripperSpec


def bind_grasp(layout, params) -> GraspTest:
    bind_object(layout, params)
    gripper = layout.robot.gripper
    if gripper is None:
        raise ValueError(f"robot {layout.robot.name!r} declares no gripper, so nothing can be grasped")
    threshold = params.threshold if params.threshold is not None else gripper.grasp_threshold
    if threshold is None:
        raise ValueError(f"give 'threshold' here or 'gripper.grasp_threshold' in robot {layout.robot.name!r}")
    if not gripper.low <= threshold <= gripper.high:
        raise ValueError(f"threshold {threshold} lies outside the gripper's range [{gripper.low}, {gripper.high}]")
    return GraspTest(params.object, params.distance, threshold, gripper.closure(threshold), gripper)


def grasped(state, test: GraspTest) -> float:
    near = length(state.objects[test.object].position - state.ee_position) < test.distance
    closed = test.gripper.closure(state.gripper) >= test.closure
    return float(near and closed)


def _describe(layout, params) -> Description:
    test = bind_grasp(layout, params)
    return Description(
        "is_grasped (derived binary)",
        f"‖{test.object} − ee‖ < {test.distance:g} and gripper closed past {test.threshold:g}",
        "0.0 or 1.0",
    )


@observation_term(
    size=fixed(1),
    bounds=constant_bounds(0.0, 1.0),
    describe=_describe,
    params=GraspParams,
    bind=bind_grasp,
    unit="0 or 1",
)
def is_grasped(state, test):
    """1 when the object is within `distance` of the EE and the gripper is closed past its threshold."""
    return grasped(state, test)


@reward_term(
    name="is_grasped",
    description="1 while the object is grasped (recorded at step time)",
    params=GraspParams,
    info_keys=("is_grasped",),
    bind=bind_grasp,
    measure=grasped,
)
def is_grasped_reward(achieved, desired, info, params, tolerance):
    return info["is_grasped"]
