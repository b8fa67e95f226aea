"""The safety check judged by PyBullet over many steps: accepted steps inside the margin, per ID, mode and policy.

    python benchmarks/safety_oracle.py [--steps N] [--ids ID ...]

Uses the same judge as tests/test_safety.py (PyBullet distance queries on the
simulated scene and along each commanded motion in a second client).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import envfactory  # noqa: E402,F401  (registers the IDs)
from bullet_oracle import POLICIES, judge_steps  # noqa: E402
from envfactory.envs import RobotEnv  # noqa: E402

SIM_IDS = ["UR5eReacherSim-v0", "UR5ePushSim-v0", "UR5ePnPSim-v0",
           "VX300SReacherSim-v0", "VX300SPushSim-v0", "VX300SPnPSim-v0"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000, help="steps per ID, mode and policy")
    parser.add_argument("--ids", nargs="*", default=SIM_IDS)
    args = parser.parse_args()
    print(f"{'ID':<22} {'mode':<6} {'policy':<9} {'accepted':>9} {'refused':>8} {'inside margin':>14} "
          f"{'lowest (m)':>11} {'s':>6}", flush=True)
    total = 0
    for env_id in args.ids:
        for ee in (False, True):
            for policy in POLICIES:
                env = RobotEnv(envfactory.blueprint(env_id, ee_action_type=ee))
                start = time.perf_counter()
                result = judge_steps(env, policy, args.steps, seed=7)
                env.close()
                total += len(result["violations"])
                print(f"{env_id:<22} {'EE' if ee else 'joint':<6} {policy:<9} {result['accepted']:>9} "
                      f"{result['rejected']:>8} {len(result['violations']):>14} {result['lowest']:>11.4f} "
                      f"{time.perf_counter() - start:>6.0f}", flush=True)
    print(f"accepted steps inside the margin, in all: {total}")


if __name__ == "__main__":
    main()
