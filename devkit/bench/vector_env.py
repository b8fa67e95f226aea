"""The native vector env: memory per env and steps per core, beside one env of ours and panda-gym's.

    python -m devkit.bench.vector_env [--ids ID ...] [--engines pybullet mujoco] [--sizes 1 4 16] [--steps 1000]
        [--rounds 3] [--markdown [PATH]]

Each row is one fresh process, random actions. Every env of a vector env starts from the one env's seed and takes
the one env's actions, so each does the one env's work and the rates compare like with like. "RSS after make"
is the process's resident memory once the env (or the N envs) is made; "peak RSS" is its high-water mark after
the timed steps (getrusage's ru_maxrss, as the panda-gym side-by-side page measures it). Steps per core are env
steps (vector steps times N) over the process's CPU time, so a busy machine slows the wall clock and not the
figure; the rate against the wall clock is beside it. panda-gym's PandaPush-v3, one env made with gym.make, is
the memory reference.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

from devkit.processes import emit, rss_mb, run_worker
from devkit.report import Report, add_markdown_option

WARM_UP = 5
PANDA_GYM_ID = "PandaPush-v3"


def work(env_id: str, num_envs: int, steps: int, seed: int, engine: str) -> dict:
    """One process: make one env (num_envs 0) or a native vector env of num_envs, then step it."""
    import resource

    import gymnasium as gym
    import numpy as np

    if env_id == PANDA_GYM_ID:
        import panda_gym  # noqa: F401  (registers its IDs)
    else:
        import envfactory  # noqa: F401
    kwargs = {"engine": engine} if engine else {}
    start = time.perf_counter()
    if num_envs:
        env = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)
    else:
        env = gym.make(env_id, **kwargs)
    make_s = time.perf_counter() - start
    rss_after_make = rss_mb()
    # every env of a vector env starts from the one env's seed and gets its actions: each does the one env's work,
    # so the rates compare the same work (random actions' costs vary widely with where the arm goes)
    single = env.single_action_space if num_envs else env.action_space
    single.seed(seed)
    actions = [single.sample() for _ in range(WARM_UP + steps)]
    if num_envs:
        env.reset(seed=[seed] * num_envs)
        actions = [np.tile(action, (num_envs, 1)) for action in actions]
    else:
        env.reset(seed=seed)
    for action in actions[:WARM_UP]:  # compiled kernels load, engine caches warm: kept out of the rate
        env.step(action)
    actions = actions[WARM_UP:]
    wall, cpu = time.perf_counter(), time.process_time()
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        if not num_envs and (terminated or truncated):
            env.reset()  # unseeded, as the vector env's autoreset resets its envs: the same next episode
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    env.close()
    env_steps = steps * max(1, num_envs)
    return {
        "id": env_id,
        "engine": engine,
        "num_envs": num_envs,
        "make_s": make_s,
        "rss_after_make_mb": rss_after_make,
        "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "steps_per_cpu_s": env_steps / cpu,
        "steps_per_wall_s": env_steps / wall,
    }


def run_one(env_id: str, num_envs: int, steps: int, seed: int, engine: str) -> dict:
    command = [sys.executable, "-m", "devkit.bench.vector_env", "--worker", env_id, "--worker-envs", str(num_envs)]
    command += ["--steps", str(steps), "--seed", str(seed), "--worker-engine", engine]
    return run_worker(command, f"{env_id} x{num_envs} ({engine or 'panda-gym'})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--ids", nargs="*", default=["UR5ePushSim-v0", "VX300SPushSim-v0"])
    parser.add_argument("--engines", nargs="*", default=["pybullet", "mujoco"])
    parser.add_argument("--sizes", nargs="*", type=int, default=[1, 4, 16])
    parser.add_argument("--steps", type=int, default=1000, help="vector steps timed per process")
    parser.add_argument("--rounds", type=int, default=3)
    add_markdown_option(parser)
    parser.add_argument("--worker", help=argparse.SUPPRESS)
    parser.add_argument("--worker-envs", type=int, default=0, help=argparse.SUPPRESS)
    parser.add_argument("--worker-engine", default="", help=argparse.SUPPRESS)
    parser.add_argument("--seed", type=int, default=0, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        emit(work(args.worker, args.worker_envs, args.steps, args.seed, args.worker_engine))
        return

    report = Report.start(parser, args, __doc__)
    report.note(f"load before: {os.getloadavg()[0]:.2f}; medians of {args.rounds} rounds, a fresh process each")
    reference = [run_one(PANDA_GYM_ID, 0, args.steps, r, "") for r in range(args.rounds)]
    panda_mb = statistics.median(r["peak_mb"] for r in reference)
    table = report.table(
        [
            "env",
            "engine",
            "envs",
            "make s",
            "RSS after make MB",
            "peak RSS MB",
            "MB per further env",
            "env steps per CPU s",
            "÷ one env",
            "env steps per wall s",
        ],
        title=f"random actions, {args.steps} vector steps timed after {WARM_UP}",
    )
    table.add(
        PANDA_GYM_ID,
        "pybullet",
        "1 (gym.make)",
        f"{statistics.median(r['make_s'] for r in reference):.2f}",
        f"{statistics.median(r['rss_after_make_mb'] for r in reference):.0f}",
        f"{panda_mb:.0f}",
        "—",
        f"{statistics.median(r['steps_per_cpu_s'] for r in reference):,.0f}",
        "—",
        f"{statistics.median(r['steps_per_wall_s'] for r in reference):,.0f}",
    )
    for env_id in args.ids:
        for engine in args.engines:
            rows = {
                size: [run_one(env_id, size, args.steps, r, engine) for r in range(args.rounds)]
                for size in (0, *args.sizes)
            }

            def median(size: int, key: str) -> float:
                return statistics.median(r[key] for r in rows[size])

            single_rate = median(0, "steps_per_cpu_s")
            smallest = min(args.sizes)
            for size in (0, *args.sizes):
                added = median(size, "rss_after_make_mb") - median(smallest, "rss_after_make_mb")
                further = f"{added / (size - smallest):.1f}" if size > smallest else "—"
                table.add(
                    env_id,
                    engine,
                    "1 (gym.make)" if size == 0 else f"{size} (make_vec)",
                    f"{median(size, 'make_s'):.2f}",
                    f"{median(size, 'rss_after_make_mb'):.0f}",
                    f"{median(size, 'peak_mb'):.0f}",
                    further,
                    f"{median(size, 'steps_per_cpu_s'):,.0f}",
                    f"{median(size, 'steps_per_cpu_s') / single_rate:.2f}×",
                    f"{median(size, 'steps_per_wall_s'):,.0f}",
                )
                print(f"  {env_id} {engine} x{size} done", file=sys.stderr, flush=True)
    report.note(
        f'load after: {os.getloadavg()[0]:.2f}. "MB per further env" is the RSS after make above the smallest '
        f"vector env's, over the envs added; \"÷ one env\" sets the env steps per CPU second beside gym.make's."
    )
    report.finish()


if __name__ == "__main__":
    main()
