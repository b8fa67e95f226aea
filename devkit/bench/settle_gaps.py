"""How far short of its target a replayed model's arm ends each simulated step, per arm joint.

    python -m devkit.bench.settle_gaps RUN_FOLDER ... [--episodes N] [--first-seed S] [--fidelity full|fast]

A Real step is done once the arm is at its target or held back at most `ros.settle.held_back` by what it
pushes (docs/concepts/real-path.md). This measures what simulated steps of the same model leave, on the goals
the parity run uses, so that bound can be set from the simulation and a twin run that exceeds it is found
out: the largest and 99th-percentile gap of each arm joint at the end of a step, and the robot's held_back.
"""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np

import envfactory  # noqa: F401  (registers the IDs)
from devkit.bench.sb3_replay import replay_arguments, sb3_class
from devkit.report import Report


def step_gaps(env, model, seeds: range) -> np.ndarray:
    """(steps, arm joints): |target - reading| at the end of each step that commanded the arm."""
    backend, unwrapped = env.unwrapped.backend, env.unwrapped
    targets: list[np.ndarray] = []
    command = backend.command_joints

    def recorded(q_arm, duration):
        targets.append(np.asarray(q_arm, float).copy())
        return command(q_arm, duration)

    backend.command_joints = recorded
    gaps = []
    for seed in seeds:
        observation, _ = env.reset(seed=seed)
        done = False
        while not done:
            targets.clear()
            action, _ = model.predict(observation, deterministic=True)
            observation, _, terminated, truncated, _ = env.step(action)
            done = terminated or truncated
            if targets:
                reading = backend.read_joints().position[unwrapped._arm_in_states]
                gaps.append(np.abs(reading - targets[-1]))
    return np.array(gaps)


def main() -> None:
    parser = replay_arguments(__doc__)
    parser.set_defaults(episodes=20, first_seed=30_000)
    parser.add_argument("--fidelity", choices=["fast", "full"], default=None, help="physics_fidelity of the replay")
    args = parser.parse_args()
    report = Report.start(parser, args, __doc__)
    table = report.table(["ID", "joint", "steps", "gap p99 rad", "gap max rad", "held_back rad"])
    for folder in args.folders:
        record = json.loads((folder / "model.json").read_text())
        kwargs = {**record["env_kwargs"], **({"physics_fidelity": args.fidelity} if args.fidelity else {})}
        env = gym.make(record["env_id"], **kwargs)
        model = sb3_class(record["algo"]).load(folder / "model.zip", env=env, device="cpu")
        gaps = step_gaps(env, model, range(args.first_seed, args.first_seed + args.episodes))
        robot = env.unwrapped.blueprint.spec.robot
        held_back = robot.ros.settle.held_back if robot.ros is not None else float("nan")
        for index, joint in enumerate(robot.arm_joints):
            column = gaps[:, index]
            table.add(
                record["env_id"],
                joint.name,
                len(column),
                f"{np.percentile(column, 99):.3f}",
                f"{column.max():.3f}",
                f"{held_back:g}",
            )
        env.close()
    report.finish()


if __name__ == "__main__":
    main()
