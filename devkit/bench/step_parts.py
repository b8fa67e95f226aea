"""Where a step's time goes: each stage of env.step timed apart, per Sim ID and engine, random actions.

    nice -n 15 python -m devkit.bench.step_parts [--rounds 3] [--steps 1000] [--ids ID ...]
        [--engines pybullet mujoco] [-k name=value ...] [--markdown [PATH]]

Every (ID, engine, round) runs in a fresh process. It first times env.step alone (the "step µs" column), then
the same number of steps again with each stage of the step wrapped in a timer:
the action's translation into a joint target, the safety proof, the checks of objects and fixtures, the
commands, the backend's cycle (the physics engine's own calls inside it apart: PyBullet's stepSimulation,
MuJoCo's rollout and mj_step), the reading of the new state, the simulation's limits, the observation, the info,
the reward and the termination. "rest" is the step's time outside every timed stage: the env's own glue and
gymnasium's wrappers. Times are the process's CPU time, not wall time, so that a loaded machine (these are
shared) slows the figures only through the caches it shares, not through the waits it imposes; reading that clock
costs about 0.7 µs, so each stage carries about 0.7 µs a call of its own timing and the parts add up to more
than the "step µs" column. Resets are not timed. The table shows medians over the rounds, µs of CPU per step.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections import Counter

from devkit.bench import SIM_IDS
from devkit.bench.versus_panda_gym import PhysicsClock
from devkit.kwarg_option import add_kwarg_option, kwargs_from
from devkit.processes import emit, run_worker
from devkit.report import Report, add_markdown_option

# (column, the env's attribute holding the object, the method timed): in the order a step runs them
STAGES = [
    ("translate", "actions", "translate"),
    ("fixture hold", "fixture_hold", "judge"),
    ("safety proof", "safety", "check"),
    ("object guard", "object_guard", "check"),
    ("commands", "backend", "command_joints"),
    ("commands", "backend", "command_gripper"),
    ("cycle", "backend", "advance"),
    ("read state", None, "_read_state"),
    ("sim limits", "sim_limits", "check"),
    ("observation", None, "_observe"),
    ("info", None, "_info"),
    ("reward", "rewards", "reward"),
    ("termination", "terminations", "terminated"),
]
COLUMNS = [
    "step µs",
    "physics",
    "cycle outside physics",
    *dict.fromkeys(column for column, _, _ in STAGES if column != "cycle"),
    "rest",
]


def _timed(times: Counter, column: str, original, clock: PhysicsClock | None = None):
    """`original`, adding its time to `times[column]`; with `clock`, the physics inside it goes to "physics"."""
    now = time.process_time

    def timed(*args, **kwargs):
        physics_before = clock.seconds if clock is not None else 0.0
        start = now()
        try:
            return original(*args, **kwargs)
        finally:
            times[column] += now() - start
            if clock is not None:
                times["physics"] += clock.seconds - physics_before

    return timed


def _run(env, steps: int, seed: int) -> float:
    """CPU seconds spent in env.step over `steps` random actions (resets not counted)."""
    env.reset(seed=seed)
    env.action_space.seed(seed)
    stepping = 0.0
    for _ in range(steps):
        action = env.action_space.sample()
        start = time.process_time()
        _, _, terminated, truncated, _ = env.step(action)
        stepping += time.process_time() - start
        if terminated or truncated:
            env.reset()
    return stepping


def work(env_id: str, steps: int, seed: int, kwargs: dict) -> dict:
    import gymnasium as gym

    import envfactory  # noqa: F401

    env = gym.make(env_id, **kwargs)
    unwrapped = env.unwrapped
    _run(env, 50, seed + 1000)  # a process's first steps load the kernels and warm the engines' caches
    plain = _run(env, steps, seed)

    clock = PhysicsClock(time.process_time)
    times: Counter = Counter()
    for column, holder, method in STAGES:
        owner = unwrapped if holder is None else getattr(unwrapped, holder)
        if owner is None:
            continue  # a stage this env does not have (no objects, no fixtures)
        # set on the instance: the env's own calls find it before the class's method
        setattr(owner, method, _timed(times, column, getattr(owner, method), clock if column == "cycle" else None))
    stepping = _run(env, steps, seed)
    env.close()
    parts = {column: 1e6 * seconds / steps for column, seconds in times.items()}
    parts["cycle outside physics"] = parts.pop("cycle", 0.0) - parts.get("physics", 0.0)
    parts["rest"] = 1e6 * stepping / steps - sum(parts.values())
    return {"id": env_id, "seed": seed, "step µs": 1e6 * plain / steps, **parts}


def run_one(label: str, steps: int, seed: int, kwargs: list[str]) -> dict:
    env_id, _, engine = label.partition(" [")
    if engine:
        kwargs = [*kwargs, f"engine={engine.rstrip(']')}"]
    command = [sys.executable, "-m", "devkit.bench.step_parts", "--worker", env_id, "--steps", str(steps)]
    command += ["--seed", str(seed), *[a for k in kwargs for a in ("-k", k)]]
    return {**run_worker(command, label), "id": label}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--ids", nargs="*", default=SIM_IDS)
    parser.add_argument("--engines", nargs="*", default=["pybullet", "mujoco"])
    add_kwarg_option(parser, help="name=value for every env")
    add_markdown_option(parser)
    parser.add_argument("--worker", help=argparse.SUPPRESS)
    parser.add_argument("--seed", type=int, default=0, help=argparse.SUPPRESS)
    args = parser.parse_args()

    if args.worker:
        emit(work(args.worker, args.steps, args.seed, kwargs_from(args.kwarg)))
        return

    report = Report.start(parser, args, __doc__)
    labels = [f"{env_id} [{engine}]" for env_id in args.ids for engine in args.engines]
    # rounds interleave the envs: a busy spell of the machine lands on every env, not on one
    results = [run_one(label, args.steps, r, args.kwarg) for r in range(args.rounds) for label in labels]
    table = report.table(
        ["env", *COLUMNS],
        title=f"µs per step, random actions (medians of {args.rounds} rounds x {args.steps} steps, fresh process "
        f"each); kwargs: {args.kwarg or 'none'}",
    )
    for label in labels:
        mine = [r for r in results if r["id"] == label]
        table.add(label, *(f"{statistics.median(r.get(c, 0.0) for r in mine):,.0f}" for c in COLUMNS))
    report.finish()


if __name__ == "__main__":
    main()
