"""One part of a training run (its start, or a resume): learn, evaluate every `eval_every` steps, checkpoint.

Each evaluation runs deterministic episodes on a separate env, on the same goals each time, appends a row to
`curve.csv`, logs it to TensorBoard (when the hyperparameters set tensorboard_log) and saves the model. An
evaluation that beats every earlier one of the run also saves it to `best/` (model, statistics and a copy of the
record naming that evaluation), so a curve that swings keeps its best policy: `--policy RUN/best/model.zip`. The
replay buffer (`replay_buffer.pkl`, needed to resume) is saved when the part ends, is stopped (Ctrl-C, SIGTERM)
or fails after an evaluation of its own. A new run that fails before its first evaluation leaves nothing
behind: neither its folder nor its TensorBoard events. At the end the curve is drawn against env steps
(`curve.png`) and against wall-clock time (`curve_wall.png`).
"""

from __future__ import annotations

import contextlib
import shutil
import signal
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from envfactory.envs.episodes import run_episodes
from envfactory.learn.curve import CurveWriter, Evaluation, plot
from envfactory.learn.models import MODEL_FILE, NORMALIZER_FILE, ModelPolicy, save
from envfactory.learn.runs import RECORD_FILE, RunRecord, release

EVAL_SEED = 10_000  # evaluation episode i resets with EVAL_SEED + i: the same goals at every evaluation
CSV_FILE, PNG_FILE, WALL_PNG_FILE, BUFFER_FILE = "curve.csv", "curve.png", "curve_wall.png", "replay_buffer.pkl"
BEST_FOLDER = "best"


def evaluate(env, policy, episodes: int) -> tuple[float, float, float]:
    """Success rate, mean return and mean length of `episodes` episodes on the fixed evaluation seeds."""

    results = run_episodes(env, policy, episodes, seed=EVAL_SEED)
    n = len(results)
    return (
        sum(r.success for r in results) / n,
        sum(r.episode_return for r in results) / n,
        sum(r.length for r in results) / n,
    )


@dataclass
class TrainResult:
    folder: Path
    evaluations: list[Evaluation]
    replay_buffer_bytes: int = 0


@dataclass
class Part:
    """What one part of a run works with."""

    folder: Path
    record: RunRecord
    model: object
    normalizer: object
    eval_env: object
    target: int
    eval_every: int
    eval_episodes: int
    writer: CurveWriter
    resumed: bool
    created: bool = False  # the folder was made by this run (removed again if it fails before evaluating)


@contextlib.contextmanager
def _sigterm_stops():
    """SIGTERM (kill, a scheduler's stop) ends the run as Ctrl-C does: with a checkpoint to resume from."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(signum, frame):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, stop)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _tensorboard(run: Part):
    """SB3's logger, writing TensorBoard events when the hyperparameters set tensorboard_log, else nowhere
    (SB3's default would make an empty temporary folder for every run)."""
    from stable_baselines3.common.logger import Logger, configure
    from stable_baselines3.common.utils import configure_logger

    data = run.record.data
    if data.get("tensorboard"):  # a resumed run writes on in its own event folder
        return configure(data["tensorboard"], ["tensorboard"])
    if run.model.tensorboard_log is None:
        return Logger(folder=None, output_formats=[])
    logger = configure_logger(0, run.model.tensorboard_log, run.folder.name, reset_num_timesteps=True)
    data["tensorboard"] = logger.get_dir()
    return logger


def learn(run: Part, progress_bar: bool, on_evaluation) -> TrainResult:
    from stable_baselines3.common.callbacks import BaseCallback

    model, record, folder = run.model, run.record, run.folder
    start, before = time.monotonic(), float(record.data.get("trained_s") or 0.0)
    evaluated = []  # evaluations of this part

    def elapsed() -> float:
        return before + time.monotonic() - start

    def checkpoint(with_buffer: bool) -> None:
        save(model, run.normalizer, folder)
        if with_buffer:
            model.save_replay_buffer(folder / BUFFER_FILE)
            # resume checks it: after a hard kill the buffer may be older than the model
            record.data["replay_buffer_timesteps"] = model.num_timesteps
        record.progress(model.num_timesteps, elapsed())

    def keep_best() -> None:
        # the checkpoint just written is the best one: copied, not serialized again
        best = folder / BEST_FOLDER
        best.mkdir(exist_ok=True)
        for name in (MODEL_FILE, NORMALIZER_FILE, RECORD_FILE):
            if (folder / name).is_file():
                shutil.copy2(folder / name, best / name)

    def evaluation(timesteps: int) -> None:
        success, mean_return, length = evaluate(run.eval_env, ModelPolicy(model, run.normalizer), run.eval_episodes)
        row = Evaluation(timesteps, success, mean_return, length, run.eval_episodes, round(elapsed(), 1))
        # the earliest of equal evaluations stays: the run's rows include those of the parts before a resume
        improved = all(success > earlier.success_rate for earlier in run.writer.rows)
        run.writer.add(row)
        evaluated.append(row)
        for name, value in (("success_rate", success), ("mean_return", mean_return), ("mean_length", length)):
            model.logger.record(f"eval/{name}", value)
        model.logger.dump(timesteps)
        if improved:
            record.data["best"] = {"timesteps": row.timesteps, "success_rate": row.success_rate}
        checkpoint(with_buffer=False)  # a run killed later keeps the model of its last evaluation
        if improved:
            keep_best()
        if on_evaluation is not None:
            on_evaluation(row)

    class EvaluateEvery(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps % run.eval_every == 0:
                evaluation(self.num_timesteps)
            return True

    logger = None
    try:
        logger = _tensorboard(run)
        model.set_logger(logger)
        record.begin_part(model.num_timesteps, run.target)
        with _sigterm_stops():
            model.learn(
                run.target - model.num_timesteps,
                callback=EvaluateEvery(),
                progress_bar=progress_bar,
                reset_num_timesteps=not run.resumed,
            )
            if not run.writer.rows or run.writer.rows[-1].timesteps != model.num_timesteps:
                evaluation(model.num_timesteps)
            checkpoint(with_buffer=True)
        record.end_part("finished")
    except KeyboardInterrupt:
        _stop(run, logger, checkpoint, "interrupted")
        raise
    except BaseException as exc:
        if not run.resumed and not evaluated:
            if logger is not None:
                logger.close()
                tensorboard = record.data.get("tensorboard")
                if tensorboard:
                    shutil.rmtree(tensorboard, ignore_errors=True)
            release(folder, run.created)
        else:  # a resumed run keeps its last checkpoint; a run with evaluations saves where it stands
            _stop(run, logger, checkpoint if evaluated else None, "failed", f"{type(exc).__name__}: {exc}")
        raise
    logger.close()
    curve = {f"{record.data['algo'].upper()} seed {record.data['seed']}": run.writer.rows}
    for file, x in ((PNG_FILE, "timesteps"), (WALL_PNG_FILE, "wall_s")):
        plot(curve, folder / file, f"{record.data['env_id']} ({record.data['algo'].upper()})", x=x)
    return TrainResult(folder, run.writer.rows, (folder / BUFFER_FILE).stat().st_size)


def _stop(run: Part, logger, checkpoint, status: str, error: str | None = None) -> None:
    """End a part early: save where it stands (model, buffer, statistics) when asked, and say so in the record."""
    try:
        if checkpoint is not None:
            checkpoint(with_buffer=True)
    finally:
        if run.record.parts and run.record.parts[-1].get("status") == "running":
            run.record.end_part(status, error)
        if logger is not None:
            logger.close()
