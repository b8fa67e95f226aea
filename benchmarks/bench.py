"""Throughput and overhead of the envs, against raw physics stepping in the same run.

    python benchmarks/bench.py [--steps N] [--ids ID ...] [--policy random|scripted]

Prints, per ID: steps/s, reset time, and the share and absolute time of
env.step spent outside physics stepping (the same backend stepping the same
substeps with no env around it), plus import and gym.make times.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time

import numpy as np


def import_time() -> float:
    code = "import time; t = time.perf_counter(); import envfactory; print(time.perf_counter() - t)"
    return float(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout)


def measure(env_id: str, steps: int, policy: str) -> dict:
    import gymnasium as gym

    from envfactory.experts import make_policy

    start = time.perf_counter()
    env = gym.make(env_id)
    make_time = time.perf_counter() - start
    unwrapped = env.unwrapped
    backend = unwrapped.backend
    env.reset(seed=0)
    env.action_space.seed(0)
    if policy == "scripted":  # contact-rich stepping: the expert pushes and carries the cube
        actor = make_policy("scripted", env)
    else:
        actor = lambda observation: env.action_space.sample() * 0.3  # noqa: E731  (moderate random motion)

    resets = []
    for i in range(20):
        t = time.perf_counter()
        env.reset(seed=i)
        resets.append(time.perf_counter() - t)

    # time spent in physics inside env.step, to tell Python overhead from
    # the extra cost of stepping a moving arm
    inside = [0.0]
    advance = backend.advance

    def timed_advance(seconds):
        t0 = time.perf_counter()
        advance(seconds)
        inside[0] += time.perf_counter() - t0

    backend.advance = timed_advance
    observation, _ = env.reset(seed=0)
    getattr(actor, "reset", lambda: None)()
    step_total = 0.0  # env.step alone: the policy's own time is left out
    for _ in range(steps):
        action = actor(observation)
        t = time.perf_counter()
        observation, _, terminated, truncated, _ = env.step(action)
        step_total += time.perf_counter() - t
        if terminated or truncated:
            observation, _ = env.reset()
            getattr(actor, "reset", lambda: None)()
    step_time = step_total / steps
    in_step_physics = inside[0] / steps
    backend.advance = advance

    substeps = max(1, round(unwrapped.blueprint.spec.env.timing.action_cycle_time / backend.dt))
    t = time.perf_counter()
    for _ in range(steps):
        backend.step_physics(substeps)
    physics_time = (time.perf_counter() - t) / steps
    env.close()
    overhead = step_time - physics_time
    return {
        "id": env_id,
        "make_s": make_time,
        "steps_per_s": 1.0 / step_time,
        "reset_ms": 1e3 * float(np.median(resets)),
        "step_ms": 1e3 * step_time,
        "physics_ms": 1e3 * physics_time,
        "outside_us": 1e6 * overhead,
        "outside_share": overhead / step_time,
        "substeps": substeps,
        "python_us": 1e6 * (step_time - in_step_physics),
        "python_share": (step_time - in_step_physics) / step_time,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--ids", nargs="*")
    parser.add_argument("--policy", choices=["random", "scripted"], default="random",
                        help="random: moderate random actions; scripted: the task's expert (contacts with the cube)")
    args = parser.parse_args()

    seconds = import_time()
    import envfactory

    ids = args.ids or sorted(i for i, r in envfactory.records().items() if r.backend == "pybullet")
    print(f"import envfactory: {seconds * 1e3:.0f} ms (budget 500 ms); policy: {args.policy}")
    header = (f"{'ID':26} {'make s':>7} {'steps/s':>8} {'reset ms':>9} {'step ms':>8} {'physics ms':>10} "
              f"{'outside µs':>10} {'outside %':>9} {'substeps':>8} {'non-physics µs':>14} {'non-physics %':>13}")
    print(header)
    for env_id in ids:
        r = measure(env_id, args.steps, args.policy)
        print(f"{r['id']:26} {r['make_s']:7.2f} {r['steps_per_s']:8.1f} {r['reset_ms']:9.2f} {r['step_ms']:8.2f} "
              f"{r['physics_ms']:10.2f} {r['outside_us']:10.0f} {100 * r['outside_share']:8.1f}% {r['substeps']:8d} "
              f"{r['python_us']:14.0f} {100 * r['python_share']:12.1f}%")
    print("outside = env.step minus raw stepping of the same substeps on a resting arm;")
    print("non-physics = env.step minus the time inside the backend's stepping during those same steps")
    print("budgets: outside physics <= 5% and <= 100 µs per step; reset <= 5 ms; gym.make <= 1 s")


if __name__ == "__main__":
    main()
