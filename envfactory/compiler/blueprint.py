"""The Blueprint: a compiled env, every term resolved, every slice and bound known.

The blueprint is immutable and needs no physics, so `describe`, the spec
snapshots and the spaces all come from it before any backend exists.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np
from pydantic import BaseModel

from envfactory.compiler.normalization import ActionScale
from envfactory.geometry.point_boxes import PointBoxes
from envfactory.schema.models import ComposedSpec
from envfactory.schema.randomization import Every
from envfactory.terms.library import (
    Description,
    EventTerm,
    ImageTerm,
    ObservationTerm,
    RewardTerm,
    SensingTerm,
    TerminationTerm,
)
from envfactory.terms.stages import NoStage, Stage


@dataclass(frozen=True)
class ObservationSlot:
    name: str
    term: ObservationTerm
    params: BaseModel
    bound: Any  # what the term function receives
    start: int
    size: int
    low: np.ndarray
    high: np.ndarray
    description: Description

    @property
    def stop(self) -> int:
        return self.start + self.size

    @property
    def goal_dependent(self) -> bool:
        return self.term.goal_dependent


@dataclass(frozen=True)
class ImageSlot:
    name: str
    term: ImageTerm
    shape: tuple[int, ...]
    low: float
    high: float


@dataclass(frozen=True)
class WeightedTerm:
    name: str
    term: RewardTerm
    weight: float
    params: BaseModel
    bound: Any


@dataclass(frozen=True)
class TerminationSlot:
    name: str
    term: TerminationTerm
    params: BaseModel
    bound: Any
    active: bool  # whether this reward type ends episodes on it (`when:` in the task)


@dataclass(frozen=True)
class EventSlot:
    name: str
    term: EventTerm
    params: BaseModel
    bound: Any  # what it samples: envfactory.terms.events.SampledQuantity
    every: Every | None  # sampled again at this interval; always at reset


@dataclass(frozen=True)
class SensingSlot:
    name: str
    term: SensingTerm
    params: BaseModel
    bound: Any  # what the term function receives to make each env's sensor


@dataclass(frozen=True)
class ActionRow:
    label: str
    low: float
    high: float
    joint: str
    unit: str


@dataclass(frozen=True)
class ActionLayout:
    ee: bool
    delta: bool
    delta_coeff: float
    rows: tuple[ActionRow, ...]
    gripper_in_action: bool
    normalize: bool = False  # the policy acts in [-1, 1], mapped onto the rows by `scale`
    yaw: bool = False  # EE mode's row after x, y, z turns the tool about the vertical (env.action.yaw)

    @property
    def size(self) -> int:
        return len(self.rows)

    @property
    def scale(self) -> ActionScale:
        arm_rows = self.size - (1 if self.gripper_in_action else 0)
        return ActionScale(self.low, self.high, [self.delta and index < arm_rows for index in range(self.size)])

    @property
    def policy_low(self) -> np.ndarray:
        """The action space the policy sees: [-1, 1] when normalised, else the declared rows."""
        return -np.ones(self.size) if self.normalize else self.low

    @property
    def policy_high(self) -> np.ndarray:
        return np.ones(self.size) if self.normalize else self.high

    @property
    def low(self) -> np.ndarray:
        return np.array([row.low for row in self.rows])

    @property
    def high(self) -> np.ndarray:
        return np.array([row.high for row in self.rows])


@dataclass(frozen=True)
class Blueprint:
    """One compiled ID: its spec, the backend that runs it, every resolved term with its slice and bounds, the
    action layout and the spaces. Immutable and physics-free: describe, the docs pages, the snapshots and the
    env's spaces all read it, and gym.make caches it per (ID, overrides, kwargs)."""

    env_id: str
    family: str
    backend: str
    goal_env: bool
    max_episode_steps: int
    spec: ComposedSpec
    asset_root: Path
    observation: tuple[ObservationSlot, ...]  # the full layout, as the standard env sees it
    action: ActionLayout
    rewards: tuple[WeightedTerm, ...]  # the set the reward type selects
    terminations: tuple[TerminationSlot, ...]
    achieved_from: str  # "ee" or an object name
    info_keys: tuple[str, ...] = field(default=())
    images: tuple[ImageSlot, ...] = field(default=())  # use_kinect: camera terms, Dict keys beside the vector
    boxes: PointBoxes | None = None  # where the EE and each object can be: the goal env's achieved-goal bounds
    stage: Callable[[], Stage] = NoStage  # builds each env's task stage (e.g. lift before place)
    events: tuple[EventSlot, ...] = field(default=())  # declared ones, applied only when randomized
    sensing: tuple[SensingSlot, ...] = field(default=())
    randomized: bool = False  # task.randomization.enabled (the randomize kwarg)
    # (fixture, the folder its URDF path is relative to): where the task file naming it lies
    fixture_folders: tuple[tuple[str, Path], ...] = field(default=())

    @property
    def policy_observation(self) -> tuple[ObservationSlot, ...]:
        """The `observation` entry: goal envs drop every goal-dependent column."""
        return policy_slots(self.observation, self.goal_env)

    @property
    def observation_size(self) -> int:
        return sum(slot.size for slot in self.policy_observation)

    def to_json(self) -> str:
        """A stable text form of everything a layout or a default change would alter."""
        spec = self.spec
        data: dict[str, Any] = {
            "id": self.env_id,
            "family": self.family,
            "backend": self.backend,
            "goal_env": self.goal_env,
            "max_episode_steps": self.max_episode_steps,
            "observation": [_slot_json(slot) for slot in self.policy_observation],
            "images": [
                {
                    "key": image.name,
                    "shape": list(image.shape),
                    "dtype": image.term.dtype.__name__,
                    "low": image.low,
                    "high": image.high,
                }
                for image in self.images
            ],
            "action": {
                "ee": self.action.ee,
                "delta": self.action.delta,
                "delta_coeff": self.action.delta_coeff,
                "normalize": self.action.normalize,
                "rows": [vars(row) for row in self.action.rows],
            },
            "reward_type": spec.env.reward_type,
            "rewards": [
                {"name": t.name, "term": t.term.name, "weight": t.weight, "params": t.params.model_dump(by_alias=True)}
                for t in self.rewards
            ],
            "terminations": [{"name": t.name, "term": t.term.name, "active": t.active} for t in self.terminations],
            "goal": spec.task.goal.model_dump(),
            "objects": {name: obj.model_dump() for name, obj in spec.task.objects.items()},
            "gripper": {"in_action": spec.task.gripper.in_action, "at_reset": spec.gripper_at_reset},
            "env": spec.env.model_dump(),
            "workspace": spec.workspace.model_dump(),
            "robot": {
                "name": spec.robot.name,
                "mount": list(spec.robot.mount),
                "home": spec.robot.home,
                "ee_frame": spec.robot.ee_frame,
                "task_frame": spec.robot.task_frame,
            },
        }
        if self.events or self.sensing:
            data["randomization"] = {
                "enabled": self.randomized,
                "events": [
                    {
                        "name": e.name,
                        "term": e.term.name,
                        "params": e.params.model_dump(),
                        "every": e.every.model_dump() if e.every else None,
                    }
                    for e in self.events
                ],
                "sensing": [
                    {"name": e.name, "term": e.term.name, "params": e.params.model_dump()} for e in self.sensing
                ],
            }
        return json.dumps(data, indent=2, sort_keys=True, default=_json_default)


def _json_default(value):
    if isinstance(value, np.ndarray):
        return [round(float(v), 6) for v in value]
    if isinstance(value, (tuple, set)):
        return list(value)
    raise TypeError(type(value))


def _slot_json(slot: ObservationSlot) -> dict:
    return {
        "idx": [slot.start, slot.stop - 1],
        "dim": slot.size,
        "term": slot.name,
        "params": slot.params.model_dump(by_alias=True),
        "component": slot.description.component,
        "source": slot.description.source,
        "unit": slot.description.unit,
        "low": slot.low,
        "high": slot.high,
    }


def policy_slots(observation: tuple[ObservationSlot, ...], goal_env: bool) -> tuple[ObservationSlot, ...]:
    """The slots of the observation vector the policy sees: a goal env's without the goal-dependent ones."""
    if not goal_env:
        return observation
    return _reindex(slot for slot in observation if not slot.goal_dependent)


def _reindex(slots) -> tuple[ObservationSlot, ...]:
    out, start = [], 0
    for slot in slots:
        out.append(
            ObservationSlot(
                slot.name, slot.term, slot.params, slot.bound, start, slot.size, slot.low, slot.high, slot.description
            )
        )
        start += slot.size
    return tuple(out)
