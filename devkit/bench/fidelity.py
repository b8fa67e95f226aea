"""The fast fidelity against full dynamics: distributions of the gaps, per ID.

    python -m devkit.bench.fidelity [--episodes 5] [--ids ID ...] [-k name=value ...] [--markdown [PATH]]
    python -m devkit.bench.fidelity --ids VX300SPnPSim-v0 -k engine=mujoco        # MuJoCo's fast fidelity
    python -m devkit.bench.fidelity --ids UR5ePnPSim-v0 -k engine=mujoco -k "overrides=[sim.mujoco.carry_held=true]"

Per ID and policy (random actions, the scripted expert): paired steps (each cycle
simulated in full and played fast from one saved state; see
devkit/oracles/fidelity_probe.py), then whole random trajectories
fed the same actions in a fast and a full env, then the expert's success per
seed in both. Prints median, 99th percentile and maximum of the EE, arm joint,
gripper and object gaps, and how the fast player played the cycles.
"""

from __future__ import annotations

import argparse
from collections import Counter

import numpy as np

import envfactory  # noqa: E402
from devkit.kwarg_option import add_kwarg_option, kwargs_from
from devkit.oracles.fidelity_probe import Gaps, PairedSteps, expert_success, paired_episode, trajectory_gaps
from devkit.report import Report, add_markdown_option


def spread(values, scale: float) -> str:
    if not values:
        return "—"
    values = scale * np.asarray(values)
    return f"{np.median(values):.4f} / {np.percentile(values, 99):.4f} / {values.max():.4f}"


def row(env_id: str, what: str, gaps: Gaps) -> list[str]:
    kinds = Counter(gaps.kinds)
    total = max(1, sum(kinds.values()))
    share = " ".join(f"{kind} {100 * kinds[kind] / total:.0f}%" for kind in PairedSteps.KINDS) if kinds else "—"
    return [
        env_id,
        what,
        str(len(gaps.ee)),
        spread(gaps.ee, 1e3),
        spread(gaps.joint, 1e3),
        spread(gaps.object_position, 1e3),
        spread(gaps.object_angle, 180 / np.pi),
        share,
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--episodes", type=int, default=5)
    parser.add_argument("--ids", nargs="*")
    add_kwarg_option(parser, help="name=value for every env made")
    add_markdown_option(parser)
    args = parser.parse_args()
    report = Report.start(parser, args, __doc__)
    kwargs = kwargs_from(args.kwarg)
    ids = args.ids or sorted(i for i, r in envfactory.records().items() if r.backend == "sim" and "Goal" not in i)
    table = report.table(
        ["ID", "measure", "steps", "EE mm", "arm joint mrad", "object mm", "object °", "cycles played"],
        title=f"gaps to full dynamics: median / p99 / max; EE, object in mm; joints in mrad; object "
        f"angle in degrees; {args.episodes} episodes per measure; kwargs: {kwargs or 'none'}",
    )
    for env_id in ids:
        for policy in ("random", "scripted"):
            gaps = Gaps()
            for seed in range(args.episodes):
                gaps.extend(paired_episode(env_id, policy, seed=seed, **kwargs)[0])
            table.add(*row(env_id, f"paired, {policy}", gaps))
        trajectories = Gaps()
        for seed in range(args.episodes):
            trajectories.extend(trajectory_gaps(env_id, seed=seed, steps=100, **kwargs))
        table.add(*row(env_id, "trajectory, random", trajectories))
        seeds = list(range(args.episodes * 2))
        fast, full = expert_success(env_id, "fast", seeds, **kwargs), expert_success(env_id, "full", seeds, **kwargs)
        changed = [s for s, a, b in zip(seeds, fast, full) if a != b]
        table.add(
            env_id,
            "expert success fast / full",
            f"{len(seeds)} episodes",
            f"{sum(fast)} / {sum(full)}",
            f"seeds that differ: {changed or 'none'}",
            "",
            "",
            "",
        )
    report.finish()


if __name__ == "__main__":
    main()
