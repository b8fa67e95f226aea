"""The scripted experts on both engines: success over seeds 0..N-1 (the episode runner: an episode counts
when the goal is reached at some step) and env.step throughput, per Push and PnP Sim ID.

    python benchmarks/engines.py [--episodes 10] [--engines pybullet mujoco] [--ids ID ...] [-k name=value ...]
        [-o OVERRIDE ...] [--markdown]

`-k ee_action_type=true` measures the experts in EE mode.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import yaml

from envfactory import registry
from envfactory.episodes import run_episodes
from envfactory.experts import make_policy


def measure(env_id: str, engine: str, episodes: int, kwargs: dict, overrides: list[str]) -> tuple[int, float]:
    env = gym.make(env_id, engine=engine, overrides=overrides, **kwargs)
    try:
        start = time.perf_counter()
        results = run_episodes(env, make_policy("scripted", env), episodes, 0)
        seconds = time.perf_counter() - start
    finally:
        env.close()
    return sum(r.success for r in results), sum(r.length for r in results) / seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--engines", nargs="*", default=["pybullet", "mujoco"])
    parser.add_argument("--ids", nargs="*", default=sorted(
        env_id for env_id, record in registry.records().items()
        if record.backend == "pybullet" and not record.goal_env and ("Push" in env_id or "PnP" in env_id)))
    parser.add_argument("-k", "--kwarg", action="append", default=[], help="name=value for every env")
    parser.add_argument("-o", "--override", action="append", default=[], help="a spec override for every env")
    parser.add_argument("--markdown", action="store_true")
    args = parser.parse_args()
    kwargs = {name: yaml.safe_load(value) for name, _, value in (pair.partition("=") for pair in args.kwarg)}
    if args.markdown:
        print("| ID | " + " | ".join(f"{engine} success | {engine} steps/s" for engine in args.engines) + " |")
        print("|---|" + "---|---|" * len(args.engines))
    for env_id in args.ids:
        cells = []
        for engine in args.engines:
            successes, rate = measure(env_id, engine, args.episodes, kwargs, args.override)
            cells += [f"{successes}/{args.episodes}", f"{rate:.0f}"]
        print(f"| {env_id} | " + " | ".join(cells) + " |" if args.markdown else f"{env_id:20s} " + "  ".join(cells))


if __name__ == "__main__":
    main()
