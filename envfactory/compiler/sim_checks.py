"""What a simulated ID needs beyond a valid spec: a physics rate that resolves its fastest motion, settings its
engine reads, and a display for the PyBullet window it asks for."""

from __future__ import annotations

from envfactory.backends.base import window_impossible
from envfactory.schema.models import ComposedSpec
from envfactory.schema.settings import MujocoSettings, SimSettings
from envfactory.schema.sources import Findings

# The settings only one engine reads; `sim.engine` and `sim.fidelity` serve both.
ENGINE_SETTINGS = {
    "pybullet": tuple(
        f"sim.{name}" for name in SimSettings.model_fields if name not in ("engine", "fidelity", "mujoco")
    ),
    "mujoco": tuple(f"sim.mujoco.{name}" for name in MujocoSettings.model_fields),
}

# Physics steps the fastest motion of a step must span. Motors and contacts are integrated once per physics
# step: a joint that crosses its range in fewer steps overshoots its limit (at 1 Hz the UR5e's Robotiq knuckle
# reads 1.26 rad against its 0.8 limit), and a motion interpolated over fewer steps meets the table in jumps.
# Measured with the UR5e pick-and-place expert under full dynamics, 3 seeds, action_speed 0.2 s: 240 Hz and
# 120 Hz (48 and 24 steps per motion) 3 of 3; 60 Hz (12 steps) 2 of 3, the held cube pressed 6 mm into the
# table; 30 Hz 0 of 3; 15 Hz the cube falls through the table. 20 steps stays on the measured-good side:
# 100 Hz at the default action_speed, where the shipped 240 Hz keeps a margin of 2.4.
MIN_STEPS_PER_MOTION = 20


def check_physics_rate(spec: ComposedSpec, engine: str, found: Findings) -> None:
    """Refuse a physics rate too low for the action's motion or the robot's fastest joint."""
    path, rate = (
        ("sim.mujoco.physics_hz", spec.sim.mujoco.physics_hz)
        if engine == "mujoco"
        else ("sim.physics_hz", spec.sim.physics_hz)
    )
    speed = spec.env.timing.action_speed
    motions = [(1.0 / speed, f"each action's motion is interpolated over action_speed {speed:g} s")]
    robot = spec.robot
    for joint, velocity in zip(robot.arm_joints, robot.arm_velocities):
        motions.append(
            (
                velocity / (joint.upper - joint.lower),
                f"{joint.name} crosses its range [{joint.lower:g}, {joint.upper:g}] in "
                f"{(joint.upper - joint.lower) / velocity:.3g} s at {velocity:g}/s",
            )
        )
    gripper = robot.gripper
    if gripper is not None:
        travel = gripper.high - gripper.low
        motions.append(
            (
                gripper.max_velocity / travel,
                f"the gripper ({gripper.joint}) goes from open to closed in "
                f"{travel / gripper.max_velocity:.3g} s at {gripper.max_velocity:g}/s",
            )
        )
    per_second, why = max(motions, key=lambda motion: motion[0])
    floor = MIN_STEPS_PER_MOTION * per_second
    if rate < floor:
        found.add(
            path,
            f"physics rate {rate:g} Hz is too low to simulate this robot: {why}, which needs at least "
            f"{MIN_STEPS_PER_MOTION} physics steps ({floor:.4g} Hz); below that joints overshoot their "
            f"limits and held objects sink into the table; valid: {path.rsplit('.', 1)[-1]} >= "
            f"{floor:.4g} (the default is 240 Hz)",
        )


def check_engine_settings(engine: str, found: Findings) -> None:
    """Refuse a setting only the other engine reads where it can only have been meant for this one: set for this
    make (an override or kwarg), or written in the file that chose this engine when that file writes nothing for
    it. A file that writes both engines' settings serves both (the engine kwarg picks one)."""
    sources = found.sources
    engine_file = sources.locations.get("sim.engine", (None,))[0] if "sim.engine" not in sources.notes else None
    writes_own = engine_file is not None and any(
        sources.locations.get(path, (None,))[0] == engine_file for path in ENGINE_SETTINGS[engine]
    )
    for other, paths in ENGINE_SETTINGS.items():
        if other == engine:
            continue
        for path in paths:
            this_make = any(key != "sim" and (path == key or path.startswith(key + ".")) for key in sources.notes)
            in_engine_file = (
                engine_file is not None and not writes_own and sources.locations.get(path, (None,))[0] == engine_file
            )
            if not (this_make or in_engine_file):
                continue
            leaf = path.rsplit(".", 1)[1]
            own = next((mine for mine in ENGINE_SETTINGS[engine] if mine.rsplit(".", 1)[1] == leaf), None)
            found.add(
                path,
                f"only {other} reads {path}, and this ID runs on {engine}"
                + (f" (its own is {own})" if own else "")
                + ": the value would go unused; set it for the engine that runs, or run on "
                f"{other} (engine={other})",
            )


def check_display(spec: ComposedSpec, engine: str, found: Findings) -> None:
    """A PyBullet window needs an X display: without one PyBullet ends the process from inside its C code."""
    if engine != "pybullet" or not spec.env.gui or not window_impossible():
        return
    found.add(
        "env.gui",
        "gui=True opens PyBullet's window, and this machine has no display (DISPLAY is unset): "
        "PyBullet would end the process with an X error; run without the GUI (gui=False, the "
        "default, and render_mode='rgb_array' for images) or where there is a display (a desktop "
        "session, ssh -X, or xvfb-run)",
    )
