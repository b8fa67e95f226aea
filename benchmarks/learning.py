"""Learning benchmark: `envfactory train` (SAC + HER by default) on the Reach goal envs.

    nice -n 15 python benchmarks/learning.py [--ids ID ...] [--seeds 0 1 2] [--steps 30000] [--every 5000]
        [--algo sac] [--out benchmarks/results/learning] [-p name=value ...] [-k name=value ...]

Each (ID, seed) is one `envfactory train` run with the per-family
hyperparameters of specs/train/<algo>.yaml (env kwargs included), evaluated
every `--every` steps on 50 fixed-goal deterministic episodes. Writes each run
folder (model, curve.csv, curve.png), plus `learning.md` (the success table),
`learning.json` and `learning.png` (every curve) in --out. Runs already
finished in --out are read back, not trained again (delete the folder to redo);
`--report-only` tabulates the curves written so far, of runs still going too.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import yaml

from envfactory.learn.curve import plot, read_csv
from envfactory.learn.hyperparams import load
from envfactory.learn.trainer import CSV_FILE, MODEL_FILE, train

IDS = ["UR5eReacherGoalSim-v0", "VX300SReacherGoalSim-v0"]


def run_one(env_id: str, seed: int, args) -> list:
    folder = args.out / f"{env_id}-{args.algo}-seed{seed}"
    if args.report_only:
        return read_csv(folder / CSV_FILE) if (folder / CSV_FILE).is_file() else []
    if (folder / MODEL_FILE).is_file() and (folder / CSV_FILE).is_file():
        rows = read_csv(folder / CSV_FILE)
        if rows and rows[-1].timesteps >= args.steps:
            return rows
    kwargs = {}
    for pair in args.kwarg:
        name, _, value = pair.partition("=")
        kwargs[name] = yaml.safe_load(value)
    result = train(env_id, folder, algo=args.algo, seed=seed, steps=args.steps, overrides=tuple(args.hyperparameter),
                   env_kwargs=kwargs, eval_every=args.every, progress_bar=False,
                   on_evaluation=lambda row: print(f"{env_id} seed {seed} step {row.timesteps}: success "
                                                   f"{row.success_rate:.0%} ({row.wall_s:.0f} s)", flush=True))
    return result.evaluations


def table(results: dict, steps: list[int]) -> str:
    lines = ["| ID | seed | " + " | ".join(f"{s // 1000}k" for s in steps) + " |",
             "|---|---|" + "---|" * len(steps)]
    for (env_id, seed), rows in results.items():
        by_step = {r.timesteps: r.success_rate for r in rows}
        cells = [f"{by_step[s]:.0%}" if s in by_step else "–" for s in steps]
        lines.append(f"| {env_id} | {seed} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--ids", nargs="+", default=IDS)
    parser.add_argument("--seeds", nargs="+", type=int, default=[0])
    parser.add_argument("--steps", type=int, default=30_000)
    parser.add_argument("--every", type=int, default=5_000)
    parser.add_argument("--algo", default="sac")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/learning"))
    parser.add_argument("-p", "--hyperparameter", action="append", default=[])
    parser.add_argument("-k", "--kwarg", action="append", default=[])
    parser.add_argument("--report-only", action="store_true",
                        help="Train nothing: tabulate and plot the curves in --out so far (runs still going too)")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    results = {(env_id, seed): run_one(env_id, seed, args) for env_id in args.ids for seed in args.seeds}
    steps = list(range(args.every, args.steps + 1, args.every))
    settings = {env_id: load(args.algo, env_id, args.hyperparameter).values for env_id in args.ids}
    markdown = table(results, steps)
    print(markdown)
    (args.out / "learning.md").write_text(markdown + "\n")
    (args.out / "learning.json").write_text(json.dumps(
        {"algo": args.algo, "steps": args.steps, "every": args.every, "overrides": args.hyperparameter,
         "kwargs": args.kwarg, "settings": settings,
         "runs": [{"env_id": env_id, "seed": seed, "curve": [r.__dict__ for r in rows]}
                  for (env_id, seed), rows in results.items()]}, indent=1, default=str))
    plot({f"{env_id} seed {seed}": rows for (env_id, seed), rows in results.items()}, args.out / "learning.png",
         f"{args.algo.upper()} + HER, success rate on 50 fixed goals")


if __name__ == "__main__":
    main()
