"""Cost of the safety check per step, on random actions, per ID and action mode.

    python -m devkit.bench.safety_bench [--steps N] [--ids ID ...] [--markdown [PATH]]

Times `SafetyCheck.check` inside real env steps (full-scale random actions from
the action space), and reports the median and 90th percentile, the poses it
measured per check, the coal distance queries per check, the share of actions it refused, and, from the same run,
the median env.step time and the check's share of it, so machine load shows.
In Push and PnP it also times the object press guard that follows an accepted
check (`ObjectPressGuard.check`, CPU time, median).
Wall-clock medians are joined by CPU-time medians (the check's own thread):
on a shared machine the two part ways, and the CPU time is the check's cost.
The pooled median is over every timed check of every ID and mode.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import envfactory  # noqa: F401  (registers the IDs)
from devkit.report import Report, add_markdown_option

SIM_IDS = [
    "UR5eReacherSim-v0",
    "UR5ePushSim-v0",
    "UR5ePnPSim-v0",
    "VX300SReacherSim-v0",
    "VX300SPushSim-v0",
    "VX300SPnPSim-v0",
]


def _timed(function, wall: list, cpu: list):
    """`function`, recording each call's wall-clock and thread CPU time."""

    def timed(*args):
        start, cpu_start = time.perf_counter(), time.thread_time()
        result = function(*args)
        wall.append(time.perf_counter() - start)
        cpu.append(time.thread_time() - cpu_start)
        return result

    return timed


def measure(env_id: str, ee: bool, steps: int) -> dict:
    import gymnasium as gym

    env = gym.make(env_id, ee_action_type=ee).unwrapped
    safety = env.safety
    times, cpu_times, guard_times, guard_cpu, poses = [], [], [], [], [0]
    anchor = safety._anchor

    def counted_anchor(*args):
        poses[0] += 1
        return anchor(*args)

    # every coal query of the check goes through exact_one (exact() asks it once per pair)
    exact_one, queries = safety.collision.exact_one, [0]

    def counted_exact_one(pair):
        queries[0] += 1
        return exact_one(pair)

    safety._anchor, safety.collision.exact_one = counted_anchor, counted_exact_one
    safety.check = _timed(safety.check, times, cpu_times)
    if env.object_guard is not None:
        env.object_guard.check = _timed(env.object_guard.check, guard_times, guard_cpu)
    env.reset(seed=0)
    env.action_space.seed(0)
    refused, step_times = 0, []
    for step in range(steps):
        action = env.action_space.sample()
        start = time.perf_counter()
        _, _, terminated, truncated, info = env.step(action)
        step_times.append(time.perf_counter() - start)
        refused += int(info["action_rejected"])
        if terminated or truncated or step % 50 == 49:
            env.reset()
    env.close()
    micro, cpu = np.array(times) * 1e6, np.array(cpu_times) * 1e6
    return {
        "median": np.median(micro),
        "p90": np.percentile(micro, 90),
        "cpu": np.median(cpu),
        "all_cpu": cpu,
        "all": micro,
        "poses": poses[0] / max(len(times), 1),
        "coal": queries[0] / max(len(times), 1),
        "refused": refused / steps,
        "checks": len(times),
        "step": np.median(step_times) * 1e6,
        "guard": np.median(guard_cpu) * 1e6 if guard_cpu else float("nan"),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--ids", nargs="*", default=SIM_IDS)
    add_markdown_option(parser)
    args = parser.parse_args()
    report = Report.start(parser, args, __doc__)
    table = report.table(
        [
            "ID",
            "mode",
            "median µs",
            "p90 µs",
            "CPU µs",
            "poses/check",
            "coal/check",
            "refused",
            "step µs",
            "share",
            "object µs",
        ],
        title=f"{args.steps} random steps per ID and mode (seed 0)",
    )
    pooled, pooled_cpu = [], []
    for env_id in args.ids:
        for ee in (False, True):
            r = measure(env_id, ee, args.steps)
            pooled.append(r["all"])
            pooled_cpu.append(r["all_cpu"])
            table.add(
                env_id,
                "EE" if ee else "joint",
                f"{r['median']:.0f}",
                f"{r['p90']:.0f}",
                f"{r['cpu']:.0f}",
                f"{r['poses']:.2f}",
                f"{r['coal']:.1f}",
                f"{r['refused']:.1%}",
                f"{r['step']:.0f}",
                f"{r['median'] / r['step']:.1%}",
                f"{r['guard']:.0f}",
            )
    report.note(
        f"pooled median: {np.median(np.concatenate(pooled)):.0f} µs wall, "
        f"{np.median(np.concatenate(pooled_cpu)):.0f} µs CPU"
    )
    report.finish()


if __name__ == "__main__":
    main()
