"""How often a goal env starts already successful: the share of resets whose achieved goal lies within
tolerance of the desired one, with goals drawn as before (`++task.goal.allow_achieved_at_reset=true`) and as
now (drawn again). Every GoalSim ID, seeds 0..N-1.

    python -m devkit.bench.free_goals --resets 300 [--markdown [PATH]]
"""

from __future__ import annotations

import argparse

import gymnasium as gym

from devkit.report import Report, add_markdown_option
from envfactory.registration import registry

ALLOWED = ["++task.goal.allow_achieved_at_reset=true"]  # a key the task files leave to its default


def free_share(env_id: str, resets: int, overrides: list[str]) -> float:
    env = gym.make(env_id, overrides=overrides)
    try:
        return sum(bool(env.reset(seed=seed)[1]["is_success"]) for seed in range(resets)) / resets
    finally:
        env.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resets", type=int, default=300)
    add_markdown_option(parser)
    args = parser.parse_args()
    report = Report.start(parser, args, __doc__)
    ids = sorted(env_id for env_id, record in registry.records().items() if record.goal_env and record.backend == "sim")
    table = report.table(
        ["goal env", "successful at reset, drawn as before", "now"],
        title=f"share of {args.resets} resets (seeds 0–{args.resets - 1}) that start successful",
    )
    for env_id in ids:
        before, now = free_share(env_id, args.resets, ALLOWED), free_share(env_id, args.resets, [])
        table.add(env_id, f"{before:.1%}", f"{now:.1%}")
    report.finish()


if __name__ == "__main__":
    main()
