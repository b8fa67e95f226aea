"""Trained models replayed by plain Stable-Baselines3: each run folder's model.zip loaded with SB3's own SAC /
TD3 / TQC class (not envfactory's loader, not its cloning subclass) and run by a bare gymnasium loop on fresh
seeds, none of them an evaluation seed of the training; success is info["is_success"] at each episode's end.

An outside check of the training's own evaluations: it shares with them only the env and the saved weights.

    python -m devkit.bench.sb3_replay RUN_FOLDER [RUN_FOLDER ...] [--episodes 50] [--first-seed 20000]
                                    [--markdown [PATH]]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import gymnasium as gym

import envfactory  # noqa: F401  (registers the IDs)
from devkit.report import Report, add_markdown_option


def sb3_class(algo: str):
    if algo == "tqc":
        from sb3_contrib import TQC

        return TQC
    import stable_baselines3

    return getattr(stable_baselines3, algo.upper())


def replay(folder: Path, episodes: int, first_seed: int, changed_kwargs: dict | None = None) -> tuple[dict, int]:
    """The run's model in its own env (its recorded kwargs, with `changed_kwargs` over them): successes."""
    record = json.loads((folder / "model.json").read_text())
    env = gym.make(record["env_id"], **{**record["env_kwargs"], **(changed_kwargs or {})})
    # the cloning term's settings are saved with the model; plain SB3 does not know them and needs none to act
    model = sb3_class(record["algo"]).load(folder / "model.zip", env=env, device="cpu")
    successes = 0
    try:
        for seed in range(first_seed, first_seed + episodes):
            observation, info = env.reset(seed=seed)
            terminated = truncated = False
            while not (terminated or truncated):
                action, _ = model.predict(observation, deterministic=True)
                observation, _, terminated, truncated, info = env.step(action)
            successes += bool(info["is_success"])
    finally:
        env.close()
    return record, successes


def replay_arguments(doc: str) -> argparse.ArgumentParser:
    """The command line of a script that replays run folders: the folders, how many episodes from which seed."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("folders", nargs="+", type=Path)
    parser.add_argument("--episodes", type=int, default=50)
    parser.add_argument("--first-seed", type=int, default=20_000)
    add_markdown_option(parser)
    return parser


def main() -> None:
    parser = replay_arguments(__doc__)
    args = parser.parse_args()
    report = Report.start(parser, args, __doc__)
    table = report.table(
        ["run", "ID", "algo", "seed", "trained steps", "episodes", "success (plain SB3)", "last evaluation of the run"]
    )
    for folder in args.folders:
        record, successes = replay(folder, args.episodes, args.first_seed)
        curve = (folder / "curve.csv").read_text().strip().splitlines()
        last = curve[-1].split(",") if len(curve) > 1 else None
        table.add(
            folder.name,
            record["env_id"],
            record["algo"],
            record["seed"],
            record["timesteps"],
            args.episodes,
            f"{successes / args.episodes:.0%}",
            f"{float(last[1]):.0%} at {int(last[0]):,}" if last else "-",
        )
    report.finish()


if __name__ == "__main__":
    main()
