"""Accepted steps that leave a simulated link inside the margin, on every Sim ID, judged by the other engine.

Each Sim ID runs on PyBullet and on MuJoCo, in joint and EE mode, under a random policy and three adversarial ones
(straight down, the action box's corners, one random action held all episode). After every accepted step the
pose the engine simulated is copied joint by joint into the other engine's model, whose own distance queries
measure each moving link against the scene's fixed obstacles (devkit/oracles/cross_engine.py): MuJoCo's
mj_geomDistance judges PyBullet's steps, PyBullet's getClosestPoints judges MuJoCo's. Neither is the safety
check's own geometry (Pinocchio and coal). On PyBullet every substep of an accepted step is also measured
against the command's straight joint-space line, the path the check proved: the column gives the largest
joint deviation from it (cycles the fast fidelity plays without substeps land on the target exactly). MuJoCo's
tracking of the line is measured by tests/test_mujoco.py.

    python -m devkit.bench.safety_cross_engine [--steps N] [--ids ID ...] [--markdown [PATH]]
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym

import envfactory
from devkit.oracles.bullet_judge import JUDGED_COLUMNS, POLICIES, judged_cells
from devkit.oracles.cross_engine import judge_end_poses
from devkit.report import Report, add_markdown_option
from envfactory.envs import RobotEnv

ENGINES = ("pybullet", "mujoco")
JUDGE = {"pybullet": "MuJoCo", "mujoco": "PyBullet"}


def sim_ids() -> list[str]:
    return sorted(
        i
        for i in gym.registry
        if i.startswith(("UR5e", "VX300S", "RX200", "NED2")) and i.endswith("Sim-v0") and "Goal" not in i
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=200, help="steps per ID, engine, mode and policy")
    parser.add_argument("--ids", nargs="*", default=None, help="default: every shipped Sim ID")
    parser.add_argument(
        "--fidelity",
        choices=("full", "fast"),
        default="full",
        help="full: every cycle simulated, the motors' tracking included (fast lands out-of-contact cycles "
        "on the proven target exactly)",
    )
    add_markdown_option(parser)
    args = parser.parse_args()
    report = Report.start(parser, args, __doc__)
    table = report.table(
        [
            "ID",
            "engine",
            "judged by",
            "mode",
            "policy",
            *JUDGED_COLUMNS,
            "off the line (mrad)",
            "s",
        ],
        title=f"{args.steps} steps per ID, engine, mode and policy (seed 7), {args.fidelity} fidelity",
    )
    total = accepted = 0
    for env_id in args.ids or sim_ids():
        for engine in ENGINES:
            for ee in (False, True):
                for policy in POLICIES:
                    env = RobotEnv(
                        envfactory.blueprint(env_id, ee_action_type=ee, engine=engine, physics_fidelity=args.fidelity)
                    )
                    start = time.perf_counter()
                    try:
                        result = judge_end_poses(env, policy, args.steps, seed=7)
                    finally:
                        env.close()
                    total += len(result["violations"])
                    accepted += result["accepted"]
                    table.add(
                        env_id,
                        engine,
                        JUDGE[engine],
                        "EE" if ee else "joint",
                        policy,
                        *judged_cells(result),
                        "-" if result["off_line"] is None else f"{1000 * result['off_line']:.2f}",
                        f"{time.perf_counter() - start:.0f}",
                    )
                    for step, value, what in result["violations"][:3]:
                        report.note(
                            f"{env_id} on {engine}, {'EE' if ee else 'joint'}, {policy}: "
                            f"step {step} ended {value} m from {what}"
                        )
    report.note(
        f"accepted steps: {accepted}; of them inside the margin, in all: {total} "
        "(lowest: inf means none came within the margin)"
    )
    report.finish()


if __name__ == "__main__":
    main()
