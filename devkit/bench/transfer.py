"""Transfer across engines: policies trained on one physics engine, with and without the task's randomization
(task.randomization: sampled physics and sensing noise), evaluated on both engines without it.

Each run folder's model.zip is loaded by plain Stable-Baselines3 (devkit/bench/sb3_replay.py) and run on 50 fixed
goals (seeds from --first-seed, none of them an evaluation seed of the training) on PyBullet and on MuJoCo, with
randomize=False and the run's other kwargs as trained. "trained on" is the run's engine and whether its env was
randomized; the curve is the run's own evaluations (on its training env) against env steps.

    python -m devkit.bench.transfer RUN_FOLDER [RUN_FOLDER ...] [--episodes 50] [--first-seed 20000]
                                  [--markdown [PATH]]
"""

from __future__ import annotations

import json
from pathlib import Path

from devkit.bench.sb3_replay import replay, replay_arguments
from devkit.report import Report
from envfactory.learn.curve import plot, read_csv

ENGINES = ("pybullet", "mujoco")


def main() -> None:
    parser = replay_arguments(__doc__)
    parser.add_argument(
        "--pictures",
        type=Path,
        help="draw each ID's training curves in this folder (the docs' img/transfer), shown on the page",
    )
    args = parser.parse_args()
    report = Report.start(parser, args, __doc__)
    table = report.table(
        [
            "run",
            "ID",
            "trained on",
            "randomized in training",
            "steps",
            *(f"success on {engine}" for engine in ENGINES),
            "curve (its own evaluations)",
        ]
    )
    curves: dict[str, dict] = {}
    for folder in args.folders:
        record = json.loads((folder / "model.json").read_text())
        kwargs = record["env_kwargs"]
        trained_on = kwargs.get("engine", "pybullet")
        curve = read_csv(folder / "curve.csv")
        curves.setdefault(record["env_id"], {})[
            f"{trained_on}, {'randomized' if kwargs.get('randomize') else 'not randomized'}, seed {record['seed']}"
        ] = curve
        successes = [
            replay(folder, args.episodes, args.first_seed, {"engine": engine, "randomize": False})[1]
            for engine in ENGINES
        ]
        table.add(
            folder.name,
            record["env_id"],
            trained_on,
            "yes" if kwargs.get("randomize") else "no",
            f"{curve[-1].timesteps:,}" if curve else "-",
            *(
                f"{count / args.episodes:.0%}" + (" (other engine)" if engine != trained_on else "")
                for engine, count in zip(ENGINES, successes)
            ),
            ", ".join(f"{row.timesteps // 1000}k {row.success_rate:.0%}" for row in curve),
        )
    if args.pictures is not None:
        args.pictures.mkdir(parents=True, exist_ok=True)
        for env_id, labelled in curves.items():
            path = args.pictures / f"{env_id}.png"
            plot(labelled, path, f"{env_id}: success on its training env")
            report.note(f"![{env_id}: training curves](../img/transfer/{path.name})")
    report.finish()


if __name__ == "__main__":
    main()
