"""Spec -> Blueprint: look up every term, bind its params, lay out the slices, and run the
checks that need the robot model (`robot_checks`) and the scene (`scene_checks`)."""

from __future__ import annotations

import xml.etree.ElementTree as ElementTree
from dataclasses import replace
from pathlib import Path

import numpy as np
from pydantic import BaseModel, ValidationError

from envfactory import backends
from envfactory.compiler import robot_checks, sim_checks
from envfactory.compiler.blueprint import (
    ActionLayout,
    ActionRow,
    Blueprint,
    EventSlot,
    ImageSlot,
    ObservationSlot,
    SensingSlot,
    TerminationSlot,
    WeightedTerm,
    policy_slots,
)
from envfactory.compiler.scene_checks import check_expert_workspace, check_scene
from envfactory.experts import EXPERTS
from envfactory.geometry.fixtures import FixtureError, fixture_urdf, read_fixture
from envfactory.geometry.frames import TaskFrame
from envfactory.geometry.obstacles import table_bounds_xy
from envfactory.geometry.point_boxes import derived_boxes
from envfactory.schema.compose import LoadedSpec
from envfactory.schema.errors import suggest
from envfactory.schema.models import ComposedSpec
from envfactory.schema.settings import SIMULATED
from envfactory.schema.sources import Findings
from envfactory.schema.validation import validation_problems
from envfactory.terms import EVENTS, IMAGES, OBSERVATIONS, REWARDS, SENSING, TERMINATIONS, TermContext, plugins
from envfactory.terms.library import UnknownReference
from envfactory.terms.rewards import step_info_keys
from envfactory.terms.stages import stage_factory

SIMULATORS = ("pybullet", "mujoco")  # the backends that integrate physics (sim.physics_hz, sim.mujoco)
STANDS_WITHIN = 0.002  # m: a fixture's bottom this near the table top stands on it


def _action_layout(spec: ComposedSpec) -> ActionLayout:
    robot, settings = spec.robot, spec.env.action
    kind = "delta" if settings.delta else "(absolute)"
    yaw = settings.ee and settings.yaw and settings.delta  # absolute + yaw is refused by compile_blueprint
    rows: list[ActionRow] = []
    if settings.ee:
        low, high = robot.ee_bounds
        for axis, lo, hi in zip("xyz", low, high):
            if settings.delta:
                # The reference pages' EE box (e.g. z in [0, 1.5]) bounds absolute positions;
                # as a delta box it would forbid ever moving down, so deltas get
                # the symmetric box of the same reach.
                reach = max(abs(lo), abs(hi))
                rows.append(ActionRow(f"Δ{axis}", -reach, reach, f"EE {axis} ({robot.task_frame} frame)", "m"))
            else:
                rows.append(ActionRow(f"absolute {axis}", lo, hi, f"EE {axis} ({robot.task_frame} frame)", "m"))
        if yaw:
            # a half turn either way is the row's reach, as the xyz rows' is the EE box's: times delta_coeff the step
            rows.append(ActionRow("Δyaw", -np.pi, np.pi, f"EE yaw (about the {robot.task_frame} frame's z)", "rad"))
    else:
        for joint in robot.arm_joints:
            # a delta row bounds the step (declared per joint, around zero); an absolute row the target
            low, high = joint.delta_box if settings.delta else (joint.lower, joint.upper)
            rows.append(ActionRow(f"{joint.label or joint.name} {kind}", low, high, joint.name, "rad"))
    if spec.task.gripper.in_action:
        gripper, entry = robot.gripper, robot.joint_states[robot.gripper_state_index]
        rows.append(ActionRow(gripper.label, gripper.low, gripper.high, entry.name, entry.unit))
    return ActionLayout(
        settings.ee,
        settings.delta,
        settings.delta_coeff,
        tuple(rows),
        spec.task.gripper.in_action,
        settings.normalize,
        yaw=yaw,
    )


def _params(model: type[BaseModel], raw: dict, path: str, found: Findings):
    try:
        return model.model_validate(raw)
    except ValidationError as exc:
        for problem in validation_problems(exc, found.sources, model):
            found.add(f"{path}.{problem.path}" if problem.path else path, problem.message)
        return None


def _lookup(table: dict, name: str, path: str, kind: str, found: Findings):
    term = table.get(name)
    if term is None:
        found.add(path, f"unknown {kind} term {name!r}{suggest(name, table)}")
    return term


def _bind(term, layout: TermContext, params, path: str, found: Findings, inert: tuple[type[Exception], ...] = ()):
    """What the term's function receives; None (the problem found, unless it is of a kind declared inert)."""
    try:
        return term.bind(layout, params)
    except ValueError as exc:
        if not isinstance(exc, inert):
            found.add(path, str(exc))
        return None


def _observation(spec: ComposedSpec, layout: TermContext, found: Findings):
    slots, start = [], 0
    for index, entry in enumerate(spec.task.observation):
        ((name, raw_params),) = entry.items()
        path = f"task.observation.{index}"
        term = _lookup(OBSERVATIONS, name, path, "observation", found)
        if term is None:
            continue
        params = _params(term.params, raw_params, f"{path}.{name}", found)
        if params is None:
            continue
        bound = _bind(term, layout, params, f"{path}.{name}", found)
        if bound is None:
            continue
        size = term.size(layout, params)
        low, high = term.bounds(layout, params, size)
        slots.append(
            ObservationSlot(
                name,
                term,
                params,
                bound,
                start,
                size,
                np.asarray(low, float).reshape(size),
                np.asarray(high, float).reshape(size),
                term.describe(layout, params),
            )
        )
        start += size
    return tuple(slots)


def _resolved_terms(
    refs: dict,
    table: dict,
    path: str,
    kind: str,
    layout: TermContext,
    found: Findings,
    inert: tuple[type[Exception], ...] = (),
):
    """(name, ref, term, params, bound) of every ref whose term, params and binding check out (a binding
    problem of an `inert` kind leaves the ref out without a finding)."""
    for name, ref in refs.items():
        term = _lookup(table, ref.term, f"{path}.{name}.term", kind, found)
        if term is None:
            continue
        params = _params(term.params, ref.params, f"{path}.{name}.params", found)
        if params is None:
            continue
        bound = _bind(term, layout, params, f"{path}.{name}", found, inert)
        if bound is not None:
            yield name, ref, term, params, bound


def _rewards(refs: dict, path: str, layout: TermContext, found: Findings):
    return tuple(
        WeightedTerm(name, term, ref.weight, params, bound)
        for name, ref, term, params, bound in _resolved_terms(refs, REWARDS, path, "reward", layout, found)
    )


def _terminations(spec: ComposedSpec, layout: TermContext, found: Findings):
    reward_type = spec.env.reward_type.lower()
    return tuple(
        TerminationSlot(name, term, params, bound, ref.when in ("always", reward_type))
        for name, ref, term, params, bound in _resolved_terms(
            spec.task.termination, TERMINATIONS, "task.termination", "termination", layout, found
        )
    )


def _randomization(
    spec: ComposedSpec, layout: TermContext, observation, goal_env: bool, env_id: str, backend: str, found: Findings
) -> tuple[tuple[EventSlot, ...], tuple[SensingSlot, ...]]:
    """The declared events and sensing terms. Their names, params and ranges are checked whether or not this ID
    turns them on (a typo is caught before anyone does); what they refer to in the task (an object, an
    observation term, a gripper) only when on: a user's task built on a shipped one may lay out its own
    observation, and a declaration left off is inert (left out of the blueprint; `describe` shows the rest)."""
    declared = spec.task.randomization
    path = "task.randomization"
    inert = () if declared.enabled else (UnknownReference,)
    events = tuple(
        EventSlot(name, term, params, bound, ref.every)
        for name, ref, term, params, bound in _resolved_terms(
            declared.events, EVENTS, f"{path}.events", "event", layout, found, inert
        )
    )
    _check_events(events, spec.env.timing.action_cycle_time, f"{path}.events", found)
    _check_masses(spec, events, f"{path}.events", found)
    sensed = replace(layout, observation_slots=policy_slots(observation, goal_env))
    robot_sensing = {name: ref for name, ref in spec.robot.sensing.items() if name not in declared.sensing}
    sensing = tuple(
        SensingSlot(name, term, params, bound)
        for refs, where in ((robot_sensing, "robot.sensing"), (declared.sensing, f"{path}.sensing"))
        for name, ref, term, params, bound in _resolved_terms(refs, SENSING, where, "sensing", sensed, found, inert)
    )
    if declared.enabled and backend not in SIMULATORS:
        found.add(
            f"{path}.enabled",
            f"{env_id} runs on backend {backend!r}: events set a simulator's physics and "
            f"sensing terms imitate a real arm's sensing, so neither applies to a real arm "
            f"(randomize Sim IDs only)",
        )
    elif declared.enabled and not (events or sensing) and not found:
        found.add(f"{path}.enabled", "randomization is on but declares no events and no sensing terms")
    return events, sensing


def _check_events(events: tuple[EventSlot, ...], cycle: float, path: str, found: Findings) -> None:
    """An engine holds one value per quantity, so two events on one would report a value it does not hold; and
    events are sampled between steps, so an interval shorter than the action cycle cannot be kept."""
    first_of: dict[tuple[str, str], str] = {}
    for event in events:
        key = (event.bound.quantity, event.bound.target)
        if key in first_of:
            what = f"{key[0]} of {key[1]}" if key[1] else key[0]
            found.add(
                f"{path}.{event.name}",
                f"sets {what}, as event {first_of[key]!r} does: the engine holds one value, so one of the two "
                f"would be reported and not applied; keep one event per quantity",
            )
        first_of.setdefault(key, event.name)
        if event.every is not None and event.every.seconds is not None and event.every.seconds < cycle:
            found.add(
                f"{path}.{event.name}.every.seconds",
                f"every {event.every.seconds:g} s is shorter than the action cycle ({cycle:g} s): events are sampled "
                f"between steps, so it could only fire once a step; write every: {{steps: 1}}, or seconds >= {cycle:g}",
            )


def _check_masses(spec: ComposedSpec, events: tuple[EventSlot, ...], path: str, found: Findings) -> None:
    """No object, nor any mass an event samples, heavier than the robot's rated payload."""
    payload, robot = spec.robot.payload, spec.robot.name
    if payload is None:
        return
    heaviest = [(f"task.objects.{name}.mass", "weighs", thing.mass) for name, thing in spec.task.objects.items()]
    heaviest += [
        (f"{path}.{e.name}", "samples up to", e.bound.high) for e in events if e.bound.quantity == "object_mass"
    ]
    for where, verb, kilograms in heaviest:
        if kilograms > payload:
            grams = kilograms / 1000.0 <= payload and kilograms >= 10 * payload  # 50 g typed as 50
            found.add(
                where,
                f"{verb} {kilograms:g} kg, over robot {robot}'s rated payload of {payload:g} kg (robot.payload)"
                + (
                    f"; looks like grams: masses are in kg ({kilograms:g} g = {kilograms / 1000:g} kg)" if grams else ""
                ),
            )


def _check_info_keys(spec: ComposedSpec, rewards, terminations, found: Findings) -> None:
    """Every step-info key a term reads must be one the step records."""
    recorded = set(step_info_keys()) | {t.term.info_keys[0] for t in rewards if t.term.measure}
    for path, slots in (("task.reward", rewards), ("task.termination", terminations)):
        for slot in slots:
            for key in slot.term.info_keys:
                if key not in recorded:
                    found.add(
                        f"{path}",
                        f"term {slot.term.name!r} ({slot.name}) reads "
                        f"step info {key!r}, which no step records "
                        f"(recorded: {', '.join(sorted(recorded))})",
                    )


def _fixtures(loaded: LoadedSpec, found: Findings) -> tuple[tuple[tuple[str, Path], ...], dict]:
    """Each fixture's URDF read as the checks see it: ((name, folder), ...) and {name: FixtureModel}; a fixture
    that cannot be used is a problem at its field."""
    spec, folders, models = loaded.spec, [], {}
    frame = TaskFrame.of(spec.robot)
    for name, fixture in spec.task.fixtures.items():
        folder = loaded.file_of(f"task.fixtures.{name}.urdf").parent
        try:
            models[name] = read_fixture(name, fixture_urdf(fixture.urdf, folder), fixture, frame)
            for problem in _stands_on_table(models[name], spec):
                found.add(f"task.fixtures.{name}.position", problem)
        except FixtureError as exc:
            found.add(f"task.fixtures.{name}.{exc.field}", str(exc))
        except (OSError, ElementTree.ParseError, AttributeError, ValueError) as exc:  # unreadable or malformed
            found.add(f"task.fixtures.{name}.urdf", f"cannot read {fixture.urdf}: {type(exc).__name__}: {exc}")
        folders.append((name, folder))
    return tuple(folders), models


def _stands_on_table(fixture, spec: ComposedSpec) -> list[str]:
    """A fixture stands on the table top, within its footprint: one that floats, sinks into the table or
    overhangs its edge is a scene no engine holds as the spec says."""
    table = spec.scene.table
    low = np.min([box.center - box.half_extents for box in fixture.boxes], axis=0)
    high = np.max([box.center + box.half_extents for box in fixture.boxes], axis=0)
    table_low, table_high = table_bounds_xy(table, TaskFrame(np.zeros(3)))
    problems = []
    if abs(low[2] - table.top_z) > STANDS_WITHIN:
        problems.append(
            f"the fixture's lowest box's bottom is at z {low[2]:.3f} (world), the table top at {table.top_z:g}: "
            "it would float or stand in the table"
        )
    if (low[:2] < table_low - STANDS_WITHIN).any() or (high[:2] > table_high + STANDS_WITHIN).any():
        problems.append(
            f"the fixture spans x/y {np.round(low[:2], 3).tolist()} to {np.round(high[:2], 3).tolist()} (world), "
            f"past the table top's {np.round(table_low, 3).tolist()} to {np.round(table_high, 3).tolist()}"
        )
    return problems


def _achieved_from(spec: ComposedSpec, found: Findings) -> str:
    source, _, quantity = spec.task.goal.achieved.partition(".")
    placeable = [*spec.task.objects, *spec.task.fixtures]
    valid = ["ee.position", *(f"{name}.position" for name in placeable)]
    if quantity != "position" or (source != "ee" and source not in placeable):
        found.add(
            "task.goal.achieved",
            f"unknown achieved goal {spec.task.goal.achieved!r}{suggest(spec.task.goal.achieved, valid)}",
        )
    for name in spec.task.goal.also:
        if name not in spec.task.objects:
            found.add(
                f"task.goal.also.{name}",
                f"{name!r} is no object of the task{suggest(name, list(spec.task.objects))}",
            )
    if spec.task.goal.lift is not None and source == "ee":
        found.add(
            "task.goal.lift",
            "the lift stage raises an object: the achieved goal must be an object's position, not 'ee.position'",
        )
    return source


def _images(spec: ComposedSpec, found: Findings) -> tuple[ImageSlot, ...]:
    if not spec.env.observation.camera_images:
        return ()
    camera = spec.scene.camera
    if camera is None:
        found.add("env.observation.camera_images", "camera images (use_kinect) need a camera: declare scene.camera")
        return ()
    slots = []
    for index, name in enumerate(camera.terms):
        term = _lookup(IMAGES, name, f"scene.camera.terms.{index}", "image", found)
        if term is not None:
            low, high = term.bounds(camera)
            slots.append(ImageSlot(name, term, term.shape(camera), low, high))
    return tuple(slots)


def _check_expert(spec: ComposedSpec, found: Findings) -> None:
    ref = spec.task.expert
    if ref is None:
        return
    expert = EXPERTS.get(ref.policy)
    if expert is None:
        found.add("task.expert.policy", f"unknown expert {ref.policy!r}{suggest(ref.policy, EXPERTS)}")
        return
    params = _params(expert.Params, ref.params, "task.expert.params", found)
    if params is None:
        return
    known = [*spec.task.objects, *spec.task.fixtures]
    if getattr(params, "object", None) not in (None, *known):
        found.add(
            "task.expert.params.object",
            f"'object: {params.object}' names no object or fixture of the task (known: {known or 'none'})",
        )
    for name, message in expert.check(params, spec):
        found.add(f"task.expert.params.{name}", message)


def _engine(spec: ComposedSpec, env_id: str, backend: str, found: Findings) -> str:
    """The backend that runs the ID: a simulated ID's physics engine is the spec's `sim.engine`."""
    if backend == SIMULATED:
        return spec.sim.engine
    if spec.sim.engine != "pybullet":
        found.add(
            "sim.engine",
            f"engine {spec.sim.engine!r} simulates; {env_id} runs on backend {backend!r}, where no engine applies",
        )
    return backend


def _check_backend(spec: ComposedSpec, env_id: str, backend: str, found: Findings) -> None:
    path = f"registration.ids.{env_id}.backend"
    # a simulated ID registers as `sim` (its engine is sim.engine's); the engines are not registration backends
    known = [SIMULATED, *(name for name in backends.available() if name not in SIMULATORS)]
    if backend not in known:
        found.add(path, f"unknown backend {backend!r}{suggest(backend, known)}")
        return
    if spec.task.fixtures and backend != SIMULATED:
        # the simulators load a fixture's URDF; a real robot has no topic for its joint, nor does a plugin backend
        # promise one
        found.add(
            path,
            f"the task stands fixtures ({', '.join(spec.task.fixtures)}), and no robot topic carries a "
            "fixture's joint: tasks with fixtures are simulation-only",
        )
        return
    if backend != "rosbridge":
        return
    ros = spec.robot.ros
    if spec.robot.simulation_only is not None:
        found.add(path, f"robot {spec.robot.name!r} is simulation-only: {spec.robot.simulation_only}")
        return
    if ros is None:
        found.add(
            path, f"backend rosbridge needs the robot's topics: robot {spec.robot.name!r} declares no 'ros:' block"
        )
        return
    for name in spec.task.objects:
        if name not in ros.object_poses:
            found.add("robot.ros.object_poses", f"backend rosbridge needs a pose topic for object {name!r}")
    uses_gripper = spec.task.gripper.in_action or spec.gripper_at_reset is not None
    if uses_gripper and ros.gripper_command is None:
        found.add(
            "robot.ros.gripper_command", "backend rosbridge needs a gripper command topic: the task drives the gripper"
        )


def _import_terms(loaded: LoadedSpec, found: Findings) -> None:
    """The user's term modules, before any term is looked up."""
    plugins.load_entry_points()
    for index, name in enumerate(loaded.spec.terms):
        try:
            plugins.import_module(name, loaded.family.folder)
        except Exception as exc:  # the module's own error, whatever its type
            found.add(f"terms.{index}", f"cannot import term module {name!r}: {type(exc).__name__}: {exc}")


def compile_blueprint(loaded: LoadedSpec, env_id: str, backend: str, goal_env: bool) -> Blueprint:
    spec = loaded.spec
    # the scene's own contradictions (boxes off the table, objects not resting on it) come first: the
    # checks below would only restate them in terms of the robot
    scene = loaded.findings()
    check_scene(spec, scene)
    scene.raise_if_any(loaded.family.name)
    found = loaded.findings()
    _import_terms(loaded, found)
    fixture_folders, fixtures = _fixtures(loaded, found)
    if len(fixtures) < len(spec.task.fixtures):
        found.raise_if_any(env_id)  # every term and check below reads the fixtures: one that did not load is said alone
    action = _action_layout(spec)
    layout = TermContext(
        spec.robot,
        spec.task,
        action.size,
        action.policy_low,
        action.policy_high,
        derived_boxes(spec, loaded.file_of("robot.model").parent, fixtures),
        episode_steps=spec.registration.max_episode_steps,
        fixtures=fixtures,
    )
    observation = _observation(spec, layout, found)
    reward_set = "sparse" if spec.env.reward_type == "Sparse" else "dense"
    rewards = _rewards(getattr(spec.task.reward, reward_set), f"task.reward.{reward_set}", layout, found)
    # the other set is compiled too, so a typo there is caught before anyone switches to it
    other = "dense" if reward_set == "sparse" else "sparse"
    _rewards(getattr(spec.task.reward, other), f"task.reward.{other}", layout, found)
    terminations = _terminations(spec, layout, found)
    _check_info_keys(spec, rewards, terminations, found)
    achieved_from = _achieved_from(spec, found)
    if spec.env.action.ee and spec.env.action.yaw and not spec.env.action.delta:
        found.add(
            "env.action.yaw",
            "the yaw row (ee_yaw_action) turns the tool by a step from where it is, so it needs delta actions "
            "(env.action.delta, the delta_action kwarg)",
        )
    if spec.env.action.ee and spec.task.goal.orientation:
        # EE mode moves the EE with the gripper held pointing down: no action turns what it holds
        found.add(
            "env.action.ee",
            f"the goal turns {', '.join(spec.task.goal.orientation)} (task.goal.orientation), and EE mode "
            "(ee_action_type) moves the EE with the gripper held pointing down, so no action could turn it: "
            "use joint mode",
        )
    _check_expert(spec, found)
    check_expert_workspace(spec, found)
    images = _images(spec, found)
    _check_backend(spec, env_id, backend, found)
    backend = _engine(spec, env_id, backend, found)
    events, sensing = _randomization(spec, layout, observation, goal_env, env_id, backend, found)
    if backend in SIMULATORS:
        sim_checks.check_physics_rate(spec, backend, found)
        sim_checks.check_engine_settings(backend, found)
        sim_checks.check_display(spec, backend, found)
    if not found:
        robot_checks.check(
            spec, loaded.file_of("robot.model").parent, found, loaded.family.path, env_id, fixture_folders
        )
    found.raise_if_any(env_id)
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
        stage=stage_factory(spec.task.goal),
        events=events,
        sensing=sensing,
        randomized=spec.task.randomization.enabled,
        fixture_folders=fixture_folders,
    )
