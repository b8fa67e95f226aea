"""The safety check's own cost, apart from what the physics around it does to the CPU caches.

    python -m devkit.bench.safety_replay [--steps N] [--ids ID ...] [--markdown [PATH]]

Records the checks an env makes on full-scale random actions (joint and EE
mode), then replays the same checks in one process and times them (CPU time
of this thread, so other processes on the machine weigh less): back to back,
and with the physics substeps of one action cycle run between two checks, as
inside `env.step`. The gap between the two is the price of cold caches, not
of the check. Also reports exact (coal) distance queries per check.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pybullet as p

import envfactory  # noqa: F401  (registers the IDs)
from devkit.bench.safety_bench import SIM_IDS
from devkit.report import Report, add_markdown_option


def record(env, steps: int) -> list[tuple]:
    calls, check = [], env.safety.check

    def recording(*args):
        calls.append(args)
        return check(*args)

    env.safety.check = recording
    env.reset(seed=0)
    env.action_space.seed(0)
    for step in range(steps):
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        if terminated or truncated or step % 50 == 49:
            env.reset()
    env.safety.check = check
    return calls


def replay(env, calls: list[tuple], substeps: int) -> tuple[float, float, float]:
    """Median CPU µs per check, exact queries per check, and the share of checks accepted."""
    safety, client = env.safety, env.backend.client
    collision = safety.collision
    # every coal query of the check goes through exact_one (exact() asks it once per pair)
    exact_one, queries = collision.exact_one, [0]

    def counted(pair):
        queries[0] += 1
        return exact_one(pair)

    collision.exact_one = counted
    safety.forget()
    times, accepted = [], 0
    for args in calls:
        for _ in range(substeps):
            p.stepSimulation(physicsClientId=client)
        start = time.thread_time()
        verdict = safety.check(*args)
        times.append(time.thread_time() - start)
        accepted += verdict.accepted
    collision.exact_one = exact_one
    return float(np.median(times) * 1e6), queries[0] / len(calls), accepted / len(calls)


def main() -> None:
    import gymnasium as gym

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--ids", nargs="*", default=SIM_IDS)
    add_markdown_option(parser)
    args = parser.parse_args()
    report = Report.start(parser, args, __doc__)
    table = report.table(
        ["ID", "mode", "warm µs", "after physics µs", "coal/check", "accepted"],
        title=f"the checks of {args.steps} random steps per ID and mode (seed 0), replayed",
    )
    warm_all = []
    for env_id in args.ids:
        for ee in (False, True):
            env = gym.make(env_id, ee_action_type=ee).unwrapped
            calls = record(env, args.steps)
            spec = env.blueprint.spec
            substeps = round(spec.env.timing.action_cycle_time * spec.sim.physics_hz)
            replay(env, calls[:20], 0)  # compiled code and caches in place
            warm, queries, accepted = replay(env, calls, 0)
            cold, _, _ = replay(env, calls, substeps)
            warm_all.append(warm)
            table.add(
                env_id, "EE" if ee else "joint", f"{warm:.0f}", f"{cold:.0f}", f"{queries:.1f}", f"{accepted:.1%}"
            )
            env.close()
    report.note(f"median over IDs and modes, warm: {np.median(warm_all):.0f} µs")
    report.finish()


if __name__ == "__main__":
    main()
