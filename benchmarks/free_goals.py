"""How often a goal env starts already successful: the share of resets whose achieved goal lies within
tolerance of the desired one, with goals drawn as before (`++task.goal.allow_achieved_at_reset=true`) and as
now (drawn again). Every GoalSim ID, seeds 0..N-1.

    python benchmarks/free_goals.py --resets 300 [--markdown]
"""

from __future__ import annotations

import argparse

import gymnasium as gym

from envfactory import registry

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
    parser.add_argument("--markdown", action="store_true")
    args = parser.parse_args()
    ids = sorted(env_id for env_id, record in registry.records().items()
                 if record.goal_env and record.backend == "pybullet")
    rows = [(env_id, free_share(env_id, args.resets, ALLOWED), free_share(env_id, args.resets, []))
            for env_id in ids]
    if args.markdown:
        print(f"| goal env | successful at reset, drawn as before | now | ({args.resets} resets) |")
        print("|---|---|---|---|")
    for env_id, before, after in rows:
        print(f"| {env_id} | {before:.1%} | {after:.1%} | |" if args.markdown else
              f"{env_id:28s} before {before:6.1%}  now {after:6.1%}")


if __name__ == "__main__":
    main()
