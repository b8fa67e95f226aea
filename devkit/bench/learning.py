"""Learning benchmark: `envfactory train` (SAC + HER by default) on the Reach goal envs, and on the Push goal
envs with and without demonstrations.

    nice -n 15 python -m devkit.bench.learning [--suite reach|push] [--ids ID ...] [--seeds 0 1 2] [--steps N]
        [--every N] [--variants plain demos] [--demo-episodes 100] [--demo-noise 0] [--algo sac] [--out FOLDER]
        [--docs FOLDER]
        [-p name=value ...] [-k name=value ...] [--report-only]

Each (ID, variant, seed) is one `envfactory train` run with the per-family
hyperparameters of specs/train/<algo>.yaml (env kwargs included), evaluated
every `--every` steps on 50 fixed-goal deterministic episodes. The `demos`
variant first collects `--demo-episodes` scripted-expert episodes with the
run's env kwargs (`envfactory collect`, into --out/datasets; `--demo-noise`: its
--action-noise) and trains with
`--demos`; `plain` trains without. Writes each run folder (model, record,
curves), plus `learning.md` (the success table), `learning.json` and
`learning.png` (every curve) in --out. With --docs, also the documentation
page (DOCS/benchmarks/learning.md: the table, the exact command, the date) and
its pictures (DOCS/img/learning/ID-steps.png and ID-wall.png: success against
env steps and against wall-clock time).

Runs already finished in --out are read back, not trained again (delete the
folder to redo); a stopped one (Ctrl-C, SIGTERM) is resumed. `--report-only`
tabulates the curves written so far, of runs still going too.

    --suite reach: the Reach goal IDs, 30k steps, every 5k, plain (the README's table)
    --suite push:  the Push goal IDs, 200k steps, every 10k, plain and demos, pages in docs/
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shlex
import sys
from datetime import datetime, timezone
from pathlib import Path

from devkit.bench.run_commands import train_commands
from devkit.kwarg_option import add_kwarg_option, kwargs_from
from devkit.report import RUN_HEADINGS, machine, revision
from envfactory.learn.curve import Evaluation, plot, read_csv
from envfactory.learn.demonstrations import ACTION_NOISE_KEY, collect, default_dataset_id
from envfactory.learn.hyperparams import load
from envfactory.learn.loop import EVAL_SEED
from envfactory.learn.runs import RunFolderError, RunRecord
from envfactory.learn.trainer import CSV_FILE, resume, train

SUITES = {
    "reach": dict(
        ids=["UR5eReacherGoalSim-v0", "VX300SReacherGoalSim-v0"],
        steps=30_000,
        every=5_000,
        variants=["plain"],
        docs=None,
    ),
    "push": dict(
        ids=["VX300SPushGoalSim-v0", "UR5ePushGoalSim-v0"],
        steps=200_000,
        every=10_000,
        variants=["plain", "demos"],
        docs=Path("docs"),
    ),
}
GOAL = 0.8  # the done-criterion of the Push runs: 80% success on the 50 evaluation goals


def folder_of(env_id: str, variant: str, seed: int, args) -> Path:
    # the plain runs keep the Reach tables' folder names
    name = f"{env_id}-{args.algo}-seed{seed}" if variant == "plain" else f"{env_id}-{args.algo}-{variant}-seed{seed}"
    return args.out / name


def env_kwargs(env_id: str, args) -> dict:
    """The kwargs a run makes the env with: its hyperparameters' env_kwargs, then -k."""
    return {**(load(args.algo, env_id, args.hyperparameter).values.get("env_kwargs") or {}), **kwargs_from(args.kwarg)}


def demonstrations(env_id: str, args) -> str:
    """The dataset folder of the expert's episodes for `env_id`, collected with the run's kwargs on first use."""
    root = (args.out / "datasets").resolve()
    folder = root / default_dataset_id(env_id)
    if not (folder / "data" / "metadata.json").is_file():
        kwargs = env_kwargs(env_id, args)
        result = collect(env_id, args.demo_episodes, env_kwargs=kwargs, data_path=root, action_noise=args.demo_noise)
        print(
            f"{env_id}: {result.episodes} expert episodes, {result.steps} steps, {result.successes} reach the goal",
            flush=True,
        )
    metadata = json.loads((folder / "data" / "metadata.json").read_text())
    episodes, noise = metadata["total_episodes"], metadata.get(ACTION_NOISE_KEY, 0.0)
    for name, held, asked in (("episodes", episodes, args.demo_episodes), ("noise", noise, args.demo_noise)):
        if held != asked:
            raise SystemExit(
                f"{folder} holds {name} {held}, not --demo-{name} {asked}: delete it to collect again, or pass "
                f"--demo-{name} {held}"
            )
    return str(folder)


def run_one(env_id: str, variant: str, seed: int, args) -> list[Evaluation]:
    folder = folder_of(env_id, variant, seed, args)
    curve = folder / CSV_FILE
    if args.report_only:
        return read_csv(curve) if curve.is_file() else []

    def report(row: Evaluation) -> None:
        print(
            f"{env_id} {variant} seed {seed} step {row.timesteps}: success {row.success_rate:.0%} ({row.wall_s:.0f} s)",
            flush=True,
        )

    rows = read_csv(curve) if curve.is_file() else []
    if rows and rows[-1].timesteps >= args.steps:
        return rows  # finished (runs of earlier versions, without a resumable record, too)
    if folder.exists():  # stopped (Ctrl-C, SIGTERM) or shorter: go on; resume says why when it cannot
        return resume(folder, steps=args.steps, progress_bar=False, on_evaluation=report).evaluations
    demos = demonstrations(env_id, args) if variant == "demos" else None
    return train(
        env_id,
        folder,
        algo=args.algo,
        seed=seed,
        steps=args.steps,
        overrides=tuple(args.hyperparameter),
        env_kwargs=kwargs_from(args.kwarg),
        eval_every=args.every,
        demos=demos,
        progress_bar=False,
        on_evaluation=report,
    ).evaluations


def step_label(steps: int) -> str:
    return f"{steps // 1000}k" if steps % 1000 == 0 else f"{steps:,}"


def first_at(rows: list[Evaluation], goal: float) -> Evaluation | None:
    return next((r for r in rows if r.success_rate >= goal), None)


def table(results: dict, steps: list[int]) -> str:
    """Success at each evaluation step, one row per run (the Reach table)."""
    lines = ["| ID | seed | " + " | ".join(step_label(s) for s in steps) + " |", "|---|---|" + "---|" * len(steps)]
    for (env_id, variant, seed), rows in results.items():
        by_step = {r.timesteps: r.success_rate for r in rows}
        cells = [f"{by_step[s]:.0%}" if s in by_step else "–" for s in steps]
        lines.append(f"| {env_id} | {seed} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def demonstration_counts(results: dict, args) -> dict:
    """How many expert episodes each run learned from (its model.json's record), 0 for a run without."""
    counts = {}
    for env_id, variant, seed in results:
        try:
            demos = RunRecord.read(folder_of(env_id, variant, seed, args)).data.get("demos") or {}
        except RunFolderError:
            demos = {}
        counts[(env_id, variant, seed)] = int(demos.get("episodes", 0))
    return counts


def goal_table(results: dict, steps: list[int], goal: float, demonstrations: dict) -> str:
    """When each run first reaches `goal`, in env steps and wall-clock time, and its success at a few steps;
    `demonstrations`: each run's count of expert episodes (demonstration_counts)."""
    # the evaluation steps some run has reached, at most eight of them spread evenly
    reached_steps = max((rows[-1].timesteps for rows in results.values() if rows), default=steps[-1])
    shown = [s for s in steps if s <= reached_steps] or steps[:1]
    marks = [shown[round(i * (len(shown) - 1) / 7)] for i in range(8)] if len(shown) > 8 else shown
    marks = sorted(set(marks))
    lines = [
        "| ID | demonstrations | seed | first ≥ {:.0%} at (steps) | (wall-clock) | ".format(goal)
        + " | ".join(step_label(s) for s in marks)
        + " | best | steps done |",
        "|---|---|---|---|---|" + "---|" * len(marks) + "---|---|",
    ]
    for (env_id, variant, seed), rows in results.items():
        by_step = {r.timesteps: r.success_rate for r in rows}
        hit = first_at(rows, goal)
        reached = (f"{hit.timesteps:,}", f"{hit.wall_s / 60:.0f} min") if hit else ("not yet", "–")
        cells = [f"{by_step[s]:.0%}" if s in by_step else "–" for s in marks]
        best = f"{max(r.success_rate for r in rows):.0%}" if rows else "–"
        done = f"{rows[-1].timesteps:,}" if rows else "0"
        count = demonstrations.get((env_id, variant, seed), 0)
        lines.append(
            f"| {env_id} | {count if count else 'none'} | {seed} | {reached[0]} | {reached[1]} | "
            + " | ".join(cells)
            + f" | {best} | {done} |"
        )
    return "\n".join(lines)


def labelled(results: dict, env_id: str) -> dict[str, list[Evaluation]]:
    return {
        f"{'with' if variant == 'demos' else 'without'} demonstrations, seed {seed}": rows
        for (run_id, variant, seed), rows in results.items()
        if run_id == env_id and rows
    }


def docs_page(results: dict, steps: list[int], args, command: str) -> str:
    images = args.docs / "img" / "learning"
    images.mkdir(parents=True, exist_ok=True)
    pictures = []
    for env_id in args.ids:
        curves = labelled(results, env_id)
        if not curves:
            continue
        for x, name in (("timesteps", "steps"), ("wall_s", "wall")):
            path = images / f"{env_id}-{name}.png"
            plot(curves, path, f"{env_id}: {args.algo.upper()} + HER, success on the fixed evaluation goals", x=x)
            pictures.append((env_id, name, path.name))
    settings = {env_id: load(args.algo, env_id, args.hyperparameter).values for env_id in args.ids}
    episodes = settings[args.ids[0]].get("eval_episodes", 50)
    commands = []
    for env_id, variant, seed in results:
        try:
            commands += train_commands(RunRecord.read(folder_of(env_id, variant, seed, args)).data)
        except RunFolderError:
            pass
    date = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    facts = [
        f"`{command}`",
        "curves of the runs in " + str(args.out) + (" so far (--report-only)" if args.report_only else ""),
        f"{date} (the page; each run's own dates are in its model.json)",
        machine(),
        f"{os.getloadavg()[0]:.2f} when the page was written",
        platform.python_version(),
        revision(),
    ]
    lines = [
        "<!-- written by devkit/bench/learning.py (python -m devkit.bench.learning): the Command row is this run's "
        "own, at its git revision -->",
        "# learning.py: Manipulation from demonstrations",
        "",
        "| Run | |",
        "|---|---|",
        *[f"| {name} | {value} |" for name, value in zip(RUN_HEADINGS, facts)],
        "",
        "Each run is `envfactory train` with the shipped hyperparameters "
        f"(`specs/train/{args.algo}.yaml`), evaluated every {args.every:,} steps on {episodes} deterministic "
        f"episodes on the same goals each time (seeds {EVAL_SEED}…{EVAL_SEED + episodes - 1}). "
        "With demonstrations, the scripted expert's episodes (as many as the table's demonstrations column "
        "says, collected with the run's env kwargs by `envfactory collect`) seed the replay "
        "buffer and the behaviour-cloning term (the `demos` block of each ID below: Q-filtered unless its "
        "q_filter is false). Wall-clock time is the run's own, "
        "evaluations included, on a machine shared with other work: compare it within this page only.",
        "",
        f"The goal: at least {GOAL:.0%} success within {args.steps:,} env steps, seed 0.",
        "",
        goal_table(results, steps, GOAL, demonstration_counts(results, args)),
        "",
    ]
    for env_id in args.ids:
        shown = [(name, file) for run_id, name, file in pictures if run_id == env_id]
        if shown:
            lines += [f"## {env_id}", ""]
            lines += [
                f"![{env_id}: success against {'env steps' if name == 'steps' else 'wall-clock time'}]"
                f"(../img/learning/{file})"
                for name, file in shown
            ]
            lines.append("")
    lines += [
        "## The runs",
        "",
        "Each run's own command (its `model.json` records every setting), after the command that collects its "
        "demonstrations (DATASET):",
        "",
        "```bash",
        *commands,
        "```",
        "",
        "The hyperparameters each ID trained with:",
        "",
        "```json",
        json.dumps(settings, indent=1),
        "```",
        "",
    ]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--suite", choices=sorted(SUITES), default="reach")
    parser.add_argument("--ids", nargs="+")
    parser.add_argument("--seeds", nargs="+", type=int, default=[0])
    parser.add_argument("--steps", type=int)
    parser.add_argument("--every", type=int)
    parser.add_argument("--variants", nargs="+", choices=["plain", "demos"])
    parser.add_argument("--demo-episodes", type=int, default=100)
    parser.add_argument("--demo-noise", type=float, default=0.0, help="collect's --action-noise")
    parser.add_argument("--algo", default="sac")
    parser.add_argument("--out", type=Path)
    parser.add_argument("--docs", type=Path, help="Write DOCS/benchmarks/learning.md and DOCS/img/learning/*.png")
    parser.add_argument("-p", "--hyperparameter", action="append", default=[])
    add_kwarg_option(parser)
    parser.add_argument(
        "--report-only",
        action="store_true",
        help="Train nothing: tabulate and plot the curves in --out so far (runs still going too)",
    )
    args = parser.parse_args()
    suite = SUITES[args.suite]
    for name in ("ids", "steps", "every", "variants", "docs"):
        if getattr(args, name) is None:
            setattr(args, name, suite[name])
    if args.out is None:
        args.out = Path("benchmarks/results/learning") / ("" if args.suite == "reach" else args.suite)
    args.out.mkdir(parents=True, exist_ok=True)
    command = "python " + shlex.join(["-m", "devkit.bench.learning", *sys.argv[1:]])

    results = {
        (env_id, variant, seed): run_one(env_id, variant, seed, args)
        for env_id in args.ids
        for variant in args.variants
        for seed in args.seeds
    }
    if args.report_only:  # a run never started is no row of the page
        results = {key: rows for key, rows in results.items() if rows}
    steps = list(range(args.every, args.steps + 1, args.every))
    settings = {env_id: load(args.algo, env_id, args.hyperparameter).values for env_id in args.ids}
    markdown = (
        table(results, steps)
        if args.variants == ["plain"]
        else goal_table(results, steps, GOAL, demonstration_counts(results, args))
    )
    print(markdown)
    (args.out / "learning.md").write_text(markdown + "\n")
    (args.out / "learning.json").write_text(
        json.dumps(
            {
                "algo": args.algo,
                "steps": args.steps,
                "every": args.every,
                "overrides": args.hyperparameter,
                "kwargs": args.kwarg,
                "settings": settings,
                "runs": [
                    {"env_id": env_id, "variant": variant, "seed": seed, "curve": [r.__dict__ for r in rows]}
                    for (env_id, variant, seed), rows in results.items()
                ],
            },
            indent=1,
            default=str,
        )
    )
    plot(
        {f"{env_id} {variant} seed {seed}": rows for (env_id, variant, seed), rows in results.items()},
        args.out / "learning.png",
        f"{args.algo.upper()} + HER, success rate on 50 fixed goals",
    )
    if args.docs is not None:
        page = args.docs / "benchmarks" / "learning.md"
        page.parent.mkdir(parents=True, exist_ok=True)
        page.write_text(docs_page(results, steps, args, command))
        print(f"wrote {page} and {args.docs / 'img' / 'learning'}/")


if __name__ == "__main__":
    main()
