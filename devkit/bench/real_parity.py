"""Simulation to the real path: policies trained on a GoalSim ID, replayed on the matching GoalReal ID against
the digital twin at the robot's stock driver timing.

Each run folder's model.zip (written by `envfactory train`) is loaded by plain Stable-Baselines3
(devkit/bench/sb3_replay.py) and run on 20 fixed goals (the seeds from --first-seed) twice: on its GoalSim ID with
the kwargs it was trained with, and on the GoalReal ID against `envfactory twin ROBOT --task TASK` started as its
own process, at the driver's stock timing (xs_sdk's 2 s profile until the env sets its own, the UR controller's
speed scaling of 1.0, Niryo's tools commander), without the model's simulation-only kwargs. Between episodes
the twin's place_object service stands in for the person who puts the cube back where the env's reset asks
(the spawn of the simulated episode of the same seed). The columns give
each side's success and mean episode length (steps), the real path's watchdog and other aborts, and its cycle:
the mean wall time of a step (from its first command to its observation) and of its motion (command to target).
Parity: the real success is at least 90% of the simulated one, in episodes at most 1.5
times as long, with no watchdog abort. Any other abort (an arm held back from its target by what it pushes, past
`ros.settle.held_back`) stops the arm and counts as a failed episode; the table counts them. A reset the env
refuses (the move home cannot be proven clear) counts among them too: the twin's place_arm service then stands
in for the person who brings the arm home by hand, and the episode starts from there.

    python -m devkit.bench.real_parity RUN_FOLDER [RUN_FOLDER ...] [--episodes 20] [--first-seed 30000]
                                     [--markdown [PATH]]
"""

from __future__ import annotations

import json
import math
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import envfactory
from devkit.bench.run_commands import train_commands
from devkit.bench.sb3_replay import replay_arguments, sb3_class
from devkit.report import Report
from envfactory.backends.base import BackendError
from envfactory.factory import simulation_only_kwargs
from envfactory.twin.twin import POSE_HZ, place_arm, place_object

PARITY_SUCCESS, PARITY_LENGTH = 0.9, 1.5
PLACED_S = 5 / POSE_HZ


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def _start_twin(robot: str, task: str, log: Path) -> tuple[subprocess.Popen, int]:
    """`envfactory twin` in a process of its own, as a user runs it; its output goes to `log`."""
    port = _free_port()
    with log.open("w") as out:
        twin = subprocess.Popen(
            [sys.executable, "-m", "envfactory.cli", "twin", robot, "--task", task, "--port", str(port)],
            stdout=out,
            stderr=subprocess.STDOUT,
            text=True,
        )
    deadline = time.monotonic() + 60
    while "twin of" not in log.read_text():  # it says where it serves once it does
        if twin.poll() is not None or time.monotonic() > deadline:
            twin.kill()
            raise RuntimeError(f"the twin did not start: {log.read_text()}")
        time.sleep(0.1)
    return twin, port


def _put_back_objects(env, port: int) -> None:
    """Between real episodes a person puts the cube back. Here the twin's place_object service does it once the
    arm is home, where the env's reset asks (the spawn a simulated reset of the same seed makes), so that each
    real episode starts as its simulated one does; without it the cube would start where the last episode
    left it."""
    backend = env.unwrapped.backend
    drive_home = backend.reset

    def reset(q_arm, gripper, objects) -> None:
        drive_home(q_arm, gripper, objects)
        for name, (position, _) in objects.items():
            place_object(port, name, position)
        if objects:
            time.sleep(PLACED_S)  # the tracker's next poses see it at rest

    backend.reset = reset


def _clear_by_hand(env, port: int):
    """When the env refuses to drive the arm home, a person brings it there by hand (freedrive) and the reset is
    asked again; here the twin's place_arm service does it, with the gripper at its reset value."""
    unwrapped = env.unwrapped
    spec = unwrapped.blueprint.spec
    gripper = None
    if spec.robot.gripper is not None:
        gripper = spec.robot.gripper.open if spec.gripper_at_reset is None else spec.gripper_at_reset

    def bring_home() -> None:
        place_arm(port, unwrapped.home, gripper)
        time.sleep(PLACED_S)

    return bring_home


def _episodes(env, model, seeds: range, clear_by_hand=None) -> dict:
    successes, lengths, aborts, steps, motions = 0, [], [], [], []
    for seed in seeds:
        try:
            observation, info = env.reset(seed=seed)
        except BackendError as refused:
            aborts.append(f"reset {seed} refused: {refused}")
            if clear_by_hand is None:
                break  # the arm stays where it is: the remaining episodes count as failed
            clear_by_hand()
            observation, info = env.reset(seed=seed)
        terminated = truncated = False
        length = 0
        while not (terminated or truncated):
            action, _ = model.predict(observation, deterministic=True)
            observation, _, terminated, truncated, info = env.step(action)
            length += 1
            timing = info.get("timing", {})
            steps += [timing["step_s"]] if math.isfinite(timing.get("step_s", math.nan)) else []
            motions += [timing["motion_s"]] if math.isfinite(timing.get("motion_s", math.nan)) else []
            if "abort_reason" in info:
                aborts.append(info["abort_reason"])
        successes += bool(info["is_success"])
        lengths.append(length)
    return {
        "success": successes / len(seeds),
        "length": float(np.mean(lengths)) if lengths else math.nan,  # of the episodes that ran
        "aborts": aborts,
        "step_s": float(np.mean(steps)) if steps else math.nan,
        "motion_s": float(np.mean(motions)) if motions else math.nan,
    }


def _how_trained(record: dict, folder: Path) -> str:
    """The run folder and the commands that made it (the dataset's first, where it learned from one)."""
    return f"`{folder}` ({record['timesteps']:,} steps in all): " + "; ".join(
        f"`{command.split('   #')[0]}`" for command in train_commands(record)
    )


def _real_id(sim_id: str) -> str:
    return sim_id.replace("GoalSim-", "GoalReal-")


def main() -> None:
    parser = replay_arguments(__doc__)
    parser.set_defaults(episodes=20, first_seed=30_000)
    args = parser.parse_args()
    report = Report.start(parser, args, __doc__)
    trainings: list[str] = []
    table = report.table(
        [
            "real ID",
            "trained steps",
            "sim success",
            "sim length",
            "real success",
            "real length",
            "watchdog aborts",
            "other aborts",
            "real step s",
            "real motion s",
            "parity",
        ]
    )
    for folder in args.folders:
        record = json.loads((folder / "model.json").read_text())
        sim_id, kwargs = record["env_id"], record["env_kwargs"]
        real_id = _real_id(sim_id)
        spec = envfactory.blueprint(real_id).spec
        seeds = range(args.first_seed, args.first_seed + args.episodes)
        model_class = sb3_class(record["algo"])

        sim_env = gym.make(sim_id, **kwargs)
        sim = _episodes(sim_env, model_class.load(folder / "model.zip", env=sim_env, device="cpu"), seeds)
        sim_env.close()

        real_kwargs = {
            name: value for name, value in kwargs.items() if name not in simulation_only_kwargs(real_id, kwargs)
        }
        twin, port = _start_twin(spec.robot.name, spec.task.name, Path(tempfile.gettempdir()) / f"twin-{real_id}.log")
        try:
            real_env = gym.make(real_id, rosbridge_port=port, allow_real_robot_motion=True, **real_kwargs)
            _put_back_objects(real_env, port)
            model = model_class.load(folder / "model.zip", env=real_env, device="cpu")
            real = _episodes(real_env, model, seeds, _clear_by_hand(real_env, port))
            real_env.close()
        finally:
            twin.terminate()
            twin.wait(timeout=30)
        watchdog = [a for a in real["aborts"] if a.startswith("the arm did not follow")]
        parity = (
            real["success"] >= PARITY_SUCCESS * sim["success"]
            and real["length"] <= PARITY_LENGTH * sim["length"]
            and not watchdog
        )
        table.add(
            real_id,
            f"{record['steps']:,}",
            f"{sim['success']:.0%}",
            f"{sim['length']:.1f}",
            f"{real['success']:.0%}",
            f"{real['length']:.1f}",
            len(watchdog),
            len(real["aborts"]) - len(watchdog),
            f"{real['step_s']:.2f}",
            f"{real['motion_s']:.2f}",
            "yes" if parity else "no",
        )
        for abort in real["aborts"][:3]:
            report.note(f"{real_id}: {abort}")
        trainings.append(_how_trained(record, folder))
        time.sleep(0.5)
    report.note(
        "How the run folders were trained (each resumed to its total of steps where the curve shows "
        "more than the first command asked for):\n\n" + "\n".join(f"- {line}" for line in trainings)
    )
    report.finish()


if __name__ == "__main__":
    main()
