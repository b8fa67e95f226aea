"""Training trials as Ray Tune trials: one Tune trial per (seed, sweep setting), each an ordinary `envfactory
train` run in its own folder (trials.py), reporting every evaluation to Tune as it happens.

Tune is Ray's own trial runner: it places the trials on the cluster's CPUs (one each, at most `cpus` at once),
records what each reported under the group folder (`tune/`, readable with `tune.ExperimentAnalysis` or
TensorBoard), and keeps a failed trial's error while the others go on. A trial is never restarted, as it has
written part of its run folder; `envfactory train --resume FOLDER` continues one.
"""

from __future__ import annotations

from pathlib import Path

from ray import tune
from tqdm import tqdm

from envfactory.cluster.trials import Trial, TrialOutcome, failure_text, run_trial
from envfactory.learn.curve import read_csv
from envfactory.learn.loop import CSV_FILE

TUNE_FOLDER = "tune"  # in the group folder: Tune's own record of the trials


def _trainable(config: dict, trials: list[Trial]) -> None:
    trial = trials[config["trial"]]

    def report(row) -> None:
        tune.report(
            {
                "timesteps": row.timesteps,
                "success_rate": row.success_rate,
                "mean_return": row.mean_return,
                "mean_length": row.mean_length,
                "wall_s": row.wall_s,
            }
        )

    run_trial(trial, on_evaluation=report)


class _Progress(tune.Callback):
    def __init__(self, bar: tqdm):
        self.bar = bar

    def on_trial_complete(self, iteration, trials, trial, **info):
        self.bar.update()

    def on_trial_error(self, iteration, trials, trial, **info):
        self.bar.update()


def run_trials(trials: list[Trial], cpus: int, progress: bool = True) -> list[TrialOutcome]:
    """Every trial as a Tune trial, at most `cpus` at once; the outcomes in the order of `trials` (a failed one
    carries its error)."""
    group = Path(trials[0].folder).parent
    with tqdm(total=len(trials), unit="trial", disable=not progress, desc="trials") as bar:
        # the trials travel through the object store; Tune's config holds only their index (Tune rewrites
        # the values of a grid into plain data, and would make a Trial a tuple)
        tuner = tune.Tuner(
            tune.with_resources(tune.with_parameters(_trainable, trials=trials), {"cpu": 1}),
            param_space={"trial": tune.grid_search(list(range(len(trials))))},
            tune_config=tune.TuneConfig(
                max_concurrent_trials=cpus, trial_dirname_creator=lambda t: Path(trials[t.config["trial"]].folder).name
            ),
            run_config=tune.RunConfig(
                storage_path=str(group / TUNE_FOLDER),
                name="trials",
                verbose=0,
                callbacks=[_Progress(bar)],
                failure_config=tune.FailureConfig(max_failures=0),
            ),
        )
        results = tuner.fit()
    outcomes: dict[int, TrialOutcome] = {}
    for result in results:
        index = result.config["trial"]
        if result.error is not None:
            outcomes[index] = TrialOutcome(trials[index], error=failure_text(result.error))
        else:
            curve = Path(trials[index].folder) / CSV_FILE
            outcomes[index] = TrialOutcome(trials[index], read_csv(curve) if curve.is_file() else [])
    return [
        outcomes.get(index, TrialOutcome(trial, error="Tune returned no result for it"))
        for index, trial in enumerate(trials)
    ]
