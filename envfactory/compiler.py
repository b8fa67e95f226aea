"""Spec -> Blueprint: every term resolved, every slice and bound known.

The blueprint is immutable and needs no physics, so `describe`, the spec
snapshots and the spaces all come from it before any backend exists.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel, ValidationError

from envfactory import backends, preflight
from envfactory.experts import EXPERTS
from envfactory.scaling import ActionScale
from envfactory.reach import PointBoxes, derived_boxes
from envfactory.spec.compose import LoadedSpec, validation_problems
from envfactory.spec.errors import Problem, SpecError, suggest
from envfactory.spec.schema import EnvSpec
from envfactory.terms import IMAGES, OBSERVATIONS, REWARDS, TERMINATIONS, Layout, plugins
from envfactory.terms.library import Description, ImageTerm, ObservationTerm, RewardTerm, TerminationTerm
from envfactory.terms.rewards import step_info_keys


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

    @property
    def size(self) -> int:
        return len(self.rows)

    @property
    def scale(self) -> ActionScale:
        arm_rows = self.size - (1 if self.gripper_in_action else 0)
        return ActionScale(self.low, self.high, [self.delta and index < arm_rows for index in range(self.size)])

    @property
    def policy_low(self) -> np.ndarray:
        """The action space the policy sees: [-1, 1] when normalised, else the seed's rows."""
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
    env_id: str
    family: str
    backend: str
    goal_env: bool
    max_episode_steps: int
    spec: EnvSpec
    asset_root: Path
    observation: tuple[ObservationSlot, ...]  # the full layout, as the standard env sees it
    action: ActionLayout
    rewards: tuple[WeightedTerm, ...]  # the set the reward type selects
    terminations: tuple[TerminationSlot, ...]
    achieved_from: str  # "ee" or an object name
    info_keys: tuple[str, ...] = field(default=())
    images: tuple[ImageSlot, ...] = field(default=())  # use_kinect: camera terms, Dict keys beside the vector
    boxes: PointBoxes | None = None  # where the EE and each object can be: the goal env's achieved-goal bounds

    @property
    def policy_observation(self) -> tuple[ObservationSlot, ...]:
        """The `observation` entry: goal envs drop every goal-dependent column."""
        if not self.goal_env:
            return self.observation
        return _reindex(slot for slot in self.observation if not slot.goal_dependent)

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
            "images": [{"key": image.name, "shape": list(image.shape), "dtype": image.term.dtype.__name__,
                        "low": image.low, "high": image.high} for image in self.images],
            "action": {
                "ee": self.action.ee,
                "delta": self.action.delta,
                "delta_coeff": self.action.delta_coeff,
                "normalize": self.action.normalize,
                "rows": [vars(row) for row in self.action.rows],
            },
            "reward_type": spec.env.reward_type,
            "rewards": [{"name": t.name, "term": t.term.name, "weight": t.weight,
                         "params": t.params.model_dump(by_alias=True)} for t in self.rewards],
            "terminations": [{"name": t.name, "term": t.term.name, "active": t.active} for t in self.terminations],
            "goal": spec.task.goal.model_dump(),
            "objects": {name: obj.model_dump() for name, obj in spec.task.objects.items()},
            "gripper": {"in_action": spec.task.gripper.in_action, "at_reset": spec.gripper_at_reset},
            "env": spec.env.model_dump(),
            "workspace": spec.workspace.model_dump(),
            "robot": {"name": spec.robot.name, "mount": list(spec.robot.mount), "home": spec.robot.home,
                      "ee_frame": spec.robot.ee_frame, "task_frame": spec.robot.task_frame},
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


def _reindex(slots) -> tuple[ObservationSlot, ...]:
    out, start = [], 0
    for slot in slots:
        out.append(ObservationSlot(slot.name, slot.term, slot.params, slot.bound, start, slot.size, slot.low,
                                   slot.high, slot.description))
        start += slot.size
    return tuple(out)


# ---------------------------------------------------------------- compile


def _action_layout(spec: EnvSpec) -> ActionLayout:
    robot, settings = spec.robot, spec.env.action
    kind = "delta" if settings.delta else "(absolute)"
    rows: list[ActionRow] = []
    if settings.ee:
        low, high = robot.ee_bounds
        for axis, lo, hi in zip("xyz", low, high):
            if settings.delta:
                # The seeds' EE box (e.g. z in [0, 1.5]) bounds absolute positions;
                # as a delta box it would forbid ever moving down, so deltas get
                # the symmetric box of the same reach.
                reach = max(abs(lo), abs(hi))
                rows.append(ActionRow(f"Δ{axis}", -reach, reach, f"EE {axis} ({robot.task_frame} frame)", "m"))
            else:
                rows.append(ActionRow(f"absolute {axis}", lo, hi, f"EE {axis} ({robot.task_frame} frame)", "m"))
    else:
        for joint in robot.arm_joints:
            # a delta row bounds the step (declared per joint, around zero); an absolute row the target
            low, high = joint.delta_box if settings.delta else (joint.lower, joint.upper)
            rows.append(ActionRow(f"{joint.label or joint.name} {kind}", low, high, joint.name, "rad"))
    if spec.task.gripper.in_action:
        gripper, entry = robot.gripper, robot.joint_states[robot.gripper_state_index]
        rows.append(ActionRow(gripper.label, gripper.low, gripper.high, entry.name, entry.unit))
    return ActionLayout(settings.ee, settings.delta, settings.delta_coeff, tuple(rows), spec.task.gripper.in_action,
                        settings.normalize)


def _params(model: type[BaseModel], raw: dict, path: str, loaded: LoadedSpec, problems: list[Problem]):
    try:
        return model.model_validate(raw)
    except ValidationError as exc:
        for problem in validation_problems(exc, loaded.sources, model):
            problems.append(loaded.problem(f"{path}.{problem.path}" if problem.path else path, problem.message))
        return None


def _lookup(table: dict, name: str, path: str, kind: str, loaded: LoadedSpec, problems: list[Problem]):
    term = table.get(name)
    if term is None:
        problems.append(loaded.problem(path, f"unknown {kind} term {name!r}{suggest(name, table)}"))
    return term


def _bind(term, layout: Layout, params, path: str, loaded: LoadedSpec, problems: list[Problem]):
    try:
        return term.bind(layout, params)
    except ValueError as exc:
        problems.append(loaded.problem(path, str(exc)))
        return None


def _observation(spec: EnvSpec, layout: Layout, loaded: LoadedSpec, problems: list[Problem]):
    slots, start = [], 0
    for index, entry in enumerate(spec.task.observation):
        (name, raw_params), = entry.items()
        path = f"task.observation.{index}"
        term = _lookup(OBSERVATIONS, name, path, "observation", loaded, problems)
        if term is None:
            continue
        params = _params(term.params, raw_params, f"{path}.{name}", loaded, problems)
        if params is None:
            continue
        bound = _bind(term, layout, params, f"{path}.{name}", loaded, problems)
        if bound is None:
            continue
        size = term.size(layout, params)
        low, high = term.bounds(layout, params, size)
        slots.append(ObservationSlot(name, term, params, bound, start, size, np.asarray(low, float).reshape(size),
                                     np.asarray(high, float).reshape(size), term.describe(layout, params)))
        start += size
    return tuple(slots)


def _resolved_terms(refs: dict, table: dict, path: str, kind: str, layout: Layout, loaded: LoadedSpec,
                    problems: list[Problem]):
    """(name, ref, term, params, bound) of every ref whose term, params and binding check out."""
    for name, ref in refs.items():
        term = _lookup(table, ref.term, f"{path}.{name}.term", kind, loaded, problems)
        if term is None:
            continue
        params = _params(term.params, ref.params, f"{path}.{name}.params", loaded, problems)
        if params is None:
            continue
        bound = _bind(term, layout, params, f"{path}.{name}", loaded, problems)
        if bound is not None:
            yield name, ref, term, params, bound


def _rewards(refs: dict, path: str, layout: Layout, loaded: LoadedSpec, problems: list[Problem]):
    return tuple(WeightedTerm(name, term, ref.weight, params, bound)
                 for name, ref, term, params, bound in _resolved_terms(refs, REWARDS, path, "reward", layout, loaded,
                                                                      problems))


def _terminations(spec: EnvSpec, layout: Layout, loaded: LoadedSpec, problems: list[Problem]):
    reward_type = spec.env.reward_type.lower()
    return tuple(TerminationSlot(name, term, params, bound, ref.when in ("always", reward_type))
                 for name, ref, term, params, bound in _resolved_terms(spec.task.termination, TERMINATIONS,
                                                                      "task.termination", "termination", layout,
                                                                      loaded, problems))


def _check_info_keys(spec: EnvSpec, rewards, terminations, loaded: LoadedSpec, problems: list[Problem]) -> None:
    """Every step-info key a term reads must be one the step records."""
    recorded = set(step_info_keys(spec)) | {t.term.info_keys[0] for t in rewards if t.term.measure}
    for path, slots in (("task.reward", rewards), ("task.termination", terminations)):
        for slot in slots:
            for key in slot.term.info_keys:
                if key not in recorded:
                    problems.append(loaded.problem(f"{path}", f"term {slot.term.name!r} ({slot.name}) reads "
                                                              f"step info {key!r}, which no step records "
                                                              f"(recorded: {', '.join(sorted(recorded))})"))


def _achieved_from(spec: EnvSpec, loaded: LoadedSpec, problems: list[Problem]) -> str:
    source, _, quantity = spec.task.goal.achieved.partition(".")
    valid = ["ee.position", *(f"{name}.position" for name in spec.task.objects)]
    if quantity != "position" or (source != "ee" and source not in spec.task.objects):
        problems.append(loaded.problem("task.goal.achieved",
                                       f"unknown achieved goal {spec.task.goal.achieved!r}"
                                       f"{suggest(spec.task.goal.achieved, valid)}"))
    elif spec.task.goal.lift is not None and source == "ee":
        problems.append(loaded.problem("task.goal.lift", "the lift stage raises an object: the achieved goal "
                                                         "must be an object's position, not 'ee.position'"))
    return source


def _images(spec: EnvSpec, loaded: LoadedSpec, problems: list[Problem]) -> tuple[ImageSlot, ...]:
    if not spec.env.use_kinect:
        return ()
    camera = spec.scene.camera
    if camera is None:
        problems.append(loaded.problem("env.use_kinect", "use_kinect needs a camera: declare scene.camera"))
        return ()
    slots = []
    for index, name in enumerate(camera.terms):
        term = _lookup(IMAGES, name, f"scene.camera.terms.{index}", "image", loaded, problems)
        if term is not None:
            low, high = term.bounds(camera)
            slots.append(ImageSlot(name, term, term.shape(camera), low, high))
    return tuple(slots)


def _check_expert(spec: EnvSpec, loaded: LoadedSpec, problems: list[Problem]) -> None:
    ref = spec.task.expert
    if ref is None:
        return
    expert = EXPERTS.get(ref.policy)
    if expert is None:
        problems.append(loaded.problem("task.expert.policy",
                                       f"unknown expert {ref.policy!r}{suggest(ref.policy, EXPERTS)}"))
        return
    params = _params(expert.Params, ref.params, "task.expert.params", loaded, problems)
    if params is None:
        return
    if getattr(params, "object", None) not in (None, *spec.task.objects):
        problems.append(loaded.problem("task.expert.params.object",
                                       f"'object: {params.object}' names no object of the task "
                                       f"(known: {list(spec.task.objects) or 'none'})"))
    for name, message in expert.check(params, spec):
        problems.append(loaded.problem(f"task.expert.params.{name}", message))


def _check_backend(spec: EnvSpec, env_id: str, backend: str, loaded: LoadedSpec, problems: list[Problem]) -> None:
    path = f"registration.ids.{env_id}.backend"
    known = backends.available()
    if backend not in known:
        problems.append(loaded.problem(path, f"unknown backend {backend!r}{suggest(backend, known)}"))
        return
    if backend != "rosbridge":
        return
    ros = spec.robot.ros
    if ros is None:
        problems.append(loaded.problem(path, f"backend rosbridge needs the robot's topics: robot "
                                             f"{spec.robot.name!r} declares no 'ros:' block"))
        return
    for name in spec.task.objects:
        if name not in ros.object_poses:
            problems.append(loaded.problem("robot.ros.object_poses", f"backend rosbridge needs a pose topic for "
                                                                     f"object {name!r}"))
    uses_gripper = spec.task.gripper.in_action or spec.gripper_at_reset is not None
    if uses_gripper and ros.gripper_command is None:
        problems.append(loaded.problem("robot.ros.gripper_command", "backend rosbridge needs a gripper command "
                                                                    "topic: the task drives the gripper"))


def _import_terms(loaded: LoadedSpec, problems: list[Problem]) -> None:
    """The user's term modules, before any term is looked up."""
    plugins.load_entry_points()
    for index, name in enumerate(loaded.spec.terms):
        try:
            plugins.import_module(name, loaded.family.folder)
        except Exception as exc:  # the module's own error, whatever its type
            problems.append(loaded.problem(f"terms.{index}", f"cannot import term module {name!r}: "
                                                             f"{type(exc).__name__}: {exc}"))


def compile_blueprint(loaded: LoadedSpec, env_id: str, backend: str, goal_env: bool) -> Blueprint:
    spec = loaded.spec
    problems: list[Problem] = []
    _import_terms(loaded, problems)
    action = _action_layout(spec)
    layout = Layout(spec.robot, spec.task, action.size, action.policy_low, action.policy_high,
                    derived_boxes(spec, loaded.file_of("robot.model").parent))
    observation = _observation(spec, layout, loaded, problems)
    reward_set = "sparse" if spec.env.reward_type == "Sparse" else "dense"
    rewards = _rewards(getattr(spec.task.reward, reward_set), f"task.reward.{reward_set}", layout, loaded, problems)
    # the other set is compiled too, so a typo there is caught before anyone switches to it
    other = "dense" if reward_set == "sparse" else "sparse"
    _rewards(getattr(spec.task.reward, other), f"task.reward.{other}", layout, loaded, problems)
    terminations = _terminations(spec, layout, loaded, problems)
    _check_info_keys(spec, rewards, terminations, loaded, problems)
    achieved_from = _achieved_from(spec, loaded, problems)
    _check_expert(spec, loaded, problems)
    images = _images(spec, loaded, problems)
    _check_backend(spec, env_id, backend, loaded, problems)
    if not problems:
        problems += preflight.check(spec, loaded.file_of("robot.model").parent, loaded.problem)
    if problems:
        raise SpecError(problems, env_id)
    info_keys = tuple(sorted({key for t in (*rewards, *terminations) for key in t.term.info_keys}))
    return Blueprint(
        env_id=env_id,
        family=loaded.family.name,
        backend=backend,
        goal_env=goal_env,
        max_episode_steps=spec.registration.max_episode_steps,
        spec=spec,
        asset_root=loaded.file_of("robot.model").parent,
        observation=observation,
        action=action,
        rewards=rewards,
        terminations=terminations,
        achieved_from=achieved_from,
        info_keys=info_keys,
        images=images,
        boxes=layout.boxes,
    )
