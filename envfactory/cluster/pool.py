"""Run work as Ray tasks: on a local Ray instance of N worker processes, or on a cluster already running
(`--address`), with a progress bar, retries for a worker that dies, and one clear error for a task that fails.

    with connected(workers=4):
        results = run_episodes_on_ray([SeedEvaluation("UR5ePushSim-v0")], range(0, 200), workers=4)

Episode work (work.py) is cut into ranges of seeds, several per worker so the fast ones take more; each
range is one task returning whole episodes. A worker process that dies (killed, out of memory, its machine
lost) costs its task a retry on another worker (Ray's max_retries): what it had done is dropped with it, so
no episode is lost and none is counted twice. An error raised by the work itself is not retried: it would
fail again, and it is reported with the ID and seeds it met.
"""

from __future__ import annotations

import contextlib
import logging
import os
from dataclasses import dataclass
from typing import Callable, Iterator

import ray
from ray.exceptions import RayError, RayTaskError
from tqdm import tqdm

from envfactory.cluster.work import Collection, EpisodeWork, ShippedFolders, split
from envfactory.learn.demonstrations import Recording

EPISODE_RETRIES = 3  # a range of episodes is run again this often when its worker dies
AUTH_MODE_VARIABLE = "RAY_AUTH_MODE"
RANGES_PER_WORKER = 4  # finer ranges balance uneven episodes and move the bar more often; each makes an env


class ClusterError(RuntimeError):
    """Work that failed on the cluster, or a cluster that cannot be reached."""


@contextlib.contextmanager
def connected(workers: int | None = None, address: str | None = None) -> Iterator[None]:
    """Ray for the block: the cluster at `address`, else a new local instance of `workers` CPUs (never one
    another program started); left alone when this process is connected already."""
    if ray.is_initialized():
        yield
        return
    try:
        ray.init(
            address=address or "local",
            num_cpus=None if address else workers,
            include_dashboard=False,
            logging_level=logging.ERROR,
            log_to_driver=False,
        )
    except (ConnectionError, RuntimeError, ValueError) as exc:
        where = f"the Ray cluster at {address}" if address else "a local Ray instance"
        # Ray's own setting, easily missed: a cluster started with token authentication (Ray's default) refuses
        # a driver that does not send the token, with no word of why
        hint = (
            (
                f" (a cluster started with token authentication needs {AUTH_MODE_VARIABLE}=token here too, and "
                f"its token in ~/.ray/auth_token)"
            )
            if address and AUTH_MODE_VARIABLE not in os.environ
            else ""
        )
        raise ClusterError(f"cannot start or reach {where}: {exc}{hint}") from None
    try:
        yield
    finally:
        ray.shutdown()


def cluster_cpus(workers: int) -> int:
    """`workers`, or when it is 0 (only --address given) the CPUs of the cluster connected to."""
    return workers or max(1, int(ray.cluster_resources().get("CPU", 1)))


class WorkError(RuntimeError):
    """An error raised by the work in a worker, as its text: not every exception survives pickling back to the
    head (one whose constructor takes other arguments than its message comes back garbled)."""


def _told(function: Callable, *arguments):
    try:
        return function(*arguments)
    except Exception as exc:
        raise WorkError(f"{type(exc).__name__}: {exc}") from None


@ray.remote(max_retries=EPISODE_RETRIES, retry_exceptions=False)
def _episodes(work: EpisodeWork, seeds: range):
    return _told(work, seeds)


@dataclass
class _Task:
    label: str  # what the task does, for an error message
    slot: int  # where its result goes
    weight: int  # its share of the progress bar


def _gather(
    submit: Callable[[int], ray.ObjectRef], tasks: list[_Task], window: int, bar: tqdm, retries: int
) -> list[list]:
    """Run tasks with at most `window` in flight (so `--workers` bounds a shared cluster too), in any order;
    each task's result under its slot. A failure raises ClusterError naming the task."""
    results: list[list] = [[] for _ in range(max((t.slot for t in tasks), default=-1) + 1)]
    pending: dict[ray.ObjectRef, _Task] = {}
    queue = list(range(len(tasks)))
    try:
        while queue or pending:
            while queue and len(pending) < window:
                index = queue.pop(0)
                pending[submit(index)] = tasks[index]
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                task = pending.pop(ref)
                try:
                    results[task.slot].append(ray.get(ref))
                except RayError as exc:
                    raise ClusterError(f"{task.label}: {_reason(exc, retries)}") from None
                bar.update(task.weight)
    finally:
        for ref in pending:  # an error or Ctrl-C: stop what is still running
            ray.cancel(ref, force=True)
    return results


def _reason(exc: RayError, retries: int) -> str:
    if isinstance(exc, RayTaskError):
        cause = exc.cause
        if isinstance(cause, WorkError):
            return str(cause)
        return f"{type(cause).__name__}: {cause}" if cause is not None else str(exc).splitlines()[0]
    times = f"{retries + 1} times" if retries else "and the task is not retried"
    return f"{type(exc).__name__} (its worker died, {times}): {str(exc).splitlines()[0]}"


def run_episodes_on_ray(works: list[EpisodeWork], seeds: range, workers: int, progress: bool = True) -> list:
    """Each work over `seeds`, spread over the cluster; per work, the merged result (work.merge), equal to
    running it in one process."""
    pieces = split(seeds, workers * RANGES_PER_WORKER)
    tasks = [
        _Task(f"{work.env_id} seeds {piece.start}..{piece.stop - 1}", slot, len(piece))
        for slot, work in enumerate(works)
        for piece in pieces
    ]
    shared = [ray.put(work) for work in works]  # sent once, not with every range (spec folders, models)
    arguments = [(shared[slot], piece) for slot in range(len(works)) for piece in pieces]
    with tqdm(total=len(works) * len(seeds), unit="episode", disable=not progress, desc="episodes") as bar:
        parts = _gather(lambda index: _episodes.remote(*arguments[index]), tasks, 2 * workers, bar, EPISODE_RETRIES)
    return [work.merge(part) for work, part in zip(works, parts)]


def recorder(workers: int, progress: bool = True) -> Callable:
    """A recorder for demonstrations.collect (`record`'s signature) that spreads the episodes over the cluster;
    call it inside `connected`."""

    def record_on_cluster(
        env_id: str, seeds: range, env_kwargs: dict | None = None, on_episode=None, action_noise: float = 0.0
    ) -> Recording:
        work = Collection(env_id, dict(env_kwargs or {}), ShippedFolders.for_ids([env_id]), action_noise)
        recording = run_episodes_on_ray([work], seeds, workers, progress)[0]
        for result in recording.results if on_episode is not None else ():
            on_episode(result)
        return recording

    return record_on_cluster
