"""The safety check judged by PyBullet over many steps: accepted steps inside the margin, per ID, mode and policy.

    python -m devkit.bench.safety_oracle [--steps N] [--ids ID ...] [--markdown [PATH]]

Uses the same judge as tests/test_safety.py (PyBullet distance queries on the
simulated scene and along each commanded motion in a second client).
"""

from __future__ import annotations

import argparse
import time

import envfactory  # noqa: E402,F401  (registers the IDs)
from devkit.oracles.bullet_judge import JUDGED_COLUMNS, POLICIES, judge_steps, judged_cells
from devkit.report import Report, add_markdown_option
from envfactory.envs import RobotEnv  # noqa: E402

SIM_IDS = [
    "UR5eReacherSim-v0",
    "UR5ePushSim-v0",
    "UR5ePnPSim-v0",
    "VX300SReacherSim-v0",
    "VX300SPushSim-v0",
    "VX300SPnPSim-v0",
]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000, help="steps per ID, mode and policy")
    parser.add_argument("--ids", nargs="*", default=SIM_IDS)
    add_markdown_option(parser)
    args = parser.parse_args()
    report = Report.start(parser, args, __doc__)
    table = report.table(
        ["ID", "mode", "policy", *JUDGED_COLUMNS, "s"],
        title=f"{args.steps} steps per ID, mode and policy (seed 7)",
    )
    total = 0
    for env_id in args.ids:
        for ee in (False, True):
            for policy in POLICIES:
                env = RobotEnv(envfactory.blueprint(env_id, ee_action_type=ee))
                start = time.perf_counter()
                result = judge_steps(env, policy, args.steps, seed=7)
                env.close()
                total += len(result["violations"])
                table.add(
                    env_id, "EE" if ee else "joint", policy, *judged_cells(result), f"{time.perf_counter() - start:.0f}"
                )
    report.note(f"accepted steps inside the margin, in all: {total}")
    report.finish()


if __name__ == "__main__":
    main()
