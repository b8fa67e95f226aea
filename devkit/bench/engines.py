"""The scripted experts (or random actions) on both engines: success over seeds 0..N-1 (the episode runner: an
episode counts when the goal is reached at some step) and env.step throughput, per Sim ID. Where an expert
succeeds on one engine and not on the other, the two engines disagree on a contact the task rests on.

    python -m devkit.bench.engines [--episodes 10] [--engines pybullet mujoco] [--ids ID ...] [-k name=value ...]
        [-o OVERRIDE ...] [--policy scripted|random] [--markdown [PATH]]

`-k ee_action_type=true` measures the experts in EE mode. Steps/s counts whole episodes (up to the first
success), the policy's own time included.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym

from devkit.kwarg_option import add_kwarg_option, kwargs_from
from devkit.report import Report, add_markdown_option
from envfactory.envs.episodes import run_episodes
from envfactory.experts import make_policy
from envfactory.registration import registry


def measure(
    env_id: str, engine: str, episodes: int, kwargs: dict, overrides: list[str], policy: str = "scripted"
) -> tuple[int, float]:
    env = gym.make(env_id, engine=engine, overrides=overrides, **kwargs)
    try:
        start = time.perf_counter()
        results = run_episodes(env, make_policy(policy, env, seed=0), episodes, 0)
        seconds = time.perf_counter() - start
    finally:
        env.close()
    return sum(r.success for r in results), sum(r.length for r in results) / seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--engines", nargs="*", default=["pybullet", "mujoco"])
    parser.add_argument(
        "--ids",
        nargs="*",
        default=sorted(
            env_id for env_id, record in registry.records().items() if record.backend == "sim" and not record.goal_env
        ),
    )
    add_kwarg_option(parser, help="name=value for every env")
    parser.add_argument("-o", "--override", action="append", default=[], help="a spec override for every env")
    parser.add_argument(
        "--policy",
        choices=["scripted", "random"],
        default="scripted",
        help="the task's scripted expert, or random actions (seeded 0)",
    )
    add_markdown_option(parser)
    args = parser.parse_args()
    report = Report.start(parser, args, __doc__)
    kwargs = kwargs_from(args.kwarg)
    settings = ", ".join([*(f"{k}={v!r}" for k, v in kwargs.items()), *args.override]) or "no kwargs"
    table = report.table(
        ["ID"] + [f"{engine} {what}" for engine in args.engines for what in ("success", "steps/s")],
        title=f"{args.policy} policy, seeds 0–{args.episodes - 1}, {settings}",
    )
    for env_id in args.ids:
        cells = []
        for engine in args.engines:
            successes, rate = measure(env_id, engine, args.episodes, kwargs, args.override, args.policy)
            cells += [f"{successes}/{args.episodes}", f"{rate:.0f}"]
        table.add(env_id, *cells)
    report.finish()


if __name__ == "__main__":
    main()
