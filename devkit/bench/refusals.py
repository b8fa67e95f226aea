"""Why random steps are refused: of the steps the safety check refuses, how many truly come within the margin
(PyBullet's distance queries along the commanded motion: another engine's shapes, not the check's) and how
many the proof only fails to clear; beside them the steps refused before the check (no IK solution, a
joint step over max_joint_delta) and by the object press guard. Per Sim ID and action mode.

    python -m devkit.bench.refusals [--steps 300] [--ids ID ...] [--modes joint ee] [--markdown [PATH]]
"""

from __future__ import annotations

import argparse
from collections import Counter

import gymnasium as gym
import numpy as np

from devkit.oracles.bullet_judge import BulletJudge
from devkit.report import Report, add_markdown_option
from envfactory.registration import registry  # noqa: E402

# a refused motion sampled this finely by the judge (per straight joint-space segment)
JUDGE_SAMPLES = 32


def classify(env_id: str, ee: bool, steps: int, seed: int = 0) -> Counter:
    env = gym.make(env_id, ee_action_type=ee)
    unwrapped = env.unwrapped
    margin = unwrapped.blueprint.spec.env.safety.surface_margin
    judge = BulletJudge(unwrapped, margin)
    counts: Counter = Counter()
    rng = np.random.default_rng(seed)
    try:
        env.reset(seed=seed)
        for step in range(steps):
            if step % 25 == 0:
                env.reset(seed=seed + step)
            state = unwrapped.state
            action = rng.uniform(env.action_space.low, env.action_space.high).astype(np.float32)
            command = unwrapped.actions.translate(action, state)
            counts["steps"] += 1
            if command.rejection:
                counts["before the check"] += 1
            else:
                verdict = unwrapped.safety.check(state.q_arm, command.q_arm, state.gripper, command.gripper)
                unwrapped.safety.forget()  # judged alone: the env's own step below checks it again
                if not verdict.accepted:
                    gripper_to = state.gripper if command.gripper is None else command.gripper
                    lowest, _ = judge.commanded(
                        state.q_arm, command.q_arm, state.gripper, gripper_to, samples=JUDGE_SAMPLES
                    )
                    counts["truly within" if lowest < margin else "not proven"] += 1
            info = env.step(action)[4]
            if info["action_rejected"] and not command.rejection and "object" in info["rejection_reason"]:
                counts["object press"] += 1
    finally:
        judge.close()
        env.close()
    return counts


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument(
        "--ids",
        nargs="*",
        default=sorted(
            env_id for env_id, record in registry.records().items() if record.backend == "sim" and not record.goal_env
        ),
    )
    parser.add_argument("--modes", nargs="*", default=["joint", "ee"])
    add_markdown_option(parser)
    args = parser.parse_args()
    report = Report.start(parser, args, __doc__)
    columns = ["before the check", "truly within", "not proven", "object press"]
    table = report.table(
        [
            "ID",
            "mode",
            "refused before the check",
            "refused, truly within the margin",
            "refused, not proven",
            "object press",
            "steps",
        ],
        title=f"shares of {args.steps} random steps per ID and mode (seed 0, a reset every 25 steps)",
    )
    for env_id in args.ids:
        for mode in args.modes:
            counts = classify(env_id, mode == "ee", args.steps)
            shares = [f"{100 * counts[c] / counts['steps']:.1f}%" for c in columns]
            table.add(env_id, mode, *shares, counts["steps"])
    report.finish()


if __name__ == "__main__":
    main()
