"""Scaling of collect and evaluate over Ray workers: episodes per second of the scripted expert on one ID, in
one process (no Ray) and as Ray tasks on a local Ray instance of 1, 2 and 4 worker CPUs; with what each worker
costs (start-up, memory) and what the head does per episode; and from those, what a 64-core cluster would
take and where its head becomes the limit.

Cold is a job's first run on a fresh Ray instance: it includes starting the worker processes, importing
envfactory in each and the first gym.make. Warm is the same job again on the same instance, whose workers
have imported everything and compiled the blueprint. The one-process and warm figures are the best of
`--repeats` runs, as other processes share the machine (its load average is on the page); more workers than
cores only share those cores. Every run gives the episodes of the single process (checked here, episode by
episode).

    python -m devkit.bench.scaling [--env-id UR5ePushGoalSim-v0] [--episodes 64] [--workers 1 2 4] [--repeats 3]
                                 [--cluster-cores 64] [--markdown [PATH]]
"""

from __future__ import annotations

import argparse
import os
import pickle
import shutil
import tempfile
import time
from pathlib import Path

import ray

from devkit.processes import rss_mb
from devkit.report import Report, add_markdown_option
from envfactory.cluster import pool
from envfactory.cluster.work import Collection, SeedEvaluation, run_here
from envfactory.learn.demonstrations import collect


def _ray_processes_mb() -> float:
    """Memory of Ray's own processes on this machine (GCS, raylet, dashboard agents), workers left out."""
    total = 0.0
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            command = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            if ("gcs_server" in command or "raylet" in command or "ray/_private" in command) and "ray::" not in command:
                total += rss_mb(int(entry.name))
        except OSError:
            continue
    return total


@ray.remote
def _probe(env_id: str) -> tuple[int, float, float]:
    """(pid, seconds to import envfactory and make the env, seconds to make it again) in a worker: its start-up
    for the job, and what each further range of seeds pays to make its env."""
    start = time.perf_counter()
    import gymnasium as gym

    import envfactory  # noqa: F401

    gym.make(env_id).close()
    first = time.perf_counter()
    gym.make(env_id).close()
    again = time.perf_counter()
    time.sleep(0.2)  # hold the worker, so the probes spread over all of them
    return os.getpid(), first - start, again - first


def _fresh_workers(workers: int, fresh: bool) -> None:
    """A new Ray instance, whose worker processes have imported nothing yet (for a cold run)."""
    if fresh:
        ray.shutdown()
        ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)


def _timed(function) -> tuple[float, object]:
    start = time.perf_counter()
    result = function()
    return time.perf_counter() - start, result


def _best(repeats: int, function) -> tuple[float, object]:
    """The fastest of `repeats` runs: the one least slowed by the machine's other processes."""
    return min((_timed(function) for _ in range(repeats)), key=lambda run: run[0])


def _collect(env_id: str, episodes: int, recorder, repeats: int = 1) -> float:
    """Seconds of a whole collect (episodes and the dataset written), into a temporary datasets folder."""
    folder = Path(tempfile.mkdtemp(prefix="scaling-datasets-"))
    try:
        seconds, _ = _best(
            repeats,
            lambda: collect(
                env_id,
                episodes,
                dataset_id="bench/scaling/expert-v0",
                data_path=folder,
                recorder=recorder,
                overwrite=True,
            ),
        )
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env-id", default="UR5ePushGoalSim-v0")
    parser.add_argument("--episodes", type=int, default=64)
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2, 4])
    parser.add_argument("--repeats", type=int, default=3, help="runs of each warm measurement; the best counts")
    parser.add_argument("--cluster-cores", type=int, default=64, help="the cluster the projection is for")
    add_markdown_option(parser)
    args = parser.parse_args()
    report = Report.start(parser, args, __doc__)
    env_id, seeds = args.env_id, range(0, args.episodes)
    evaluation, collection = SeedEvaluation(env_id), Collection(env_id)

    # the reference: one process, no Ray (the first make of the process is paid before the clock starts)
    run_here(evaluation, range(0, 1))
    evaluate_s, reference = _best(args.repeats, lambda: run_here(evaluation, seeds))
    recording = run_here(collection, seeds)
    collect_s = _collect(env_id, args.episodes, lambda *a: run_here(collection, a[1]), args.repeats)
    # the head's own share of collect: the dataset written from episodes already recorded
    write_s = _collect(env_id, args.episodes, lambda *a: recording, args.repeats)
    steps = sum(r.length for r in reference)
    episode_bytes = len(pickle.dumps(recording.episodes)) / len(recording.episodes)
    report.note(
        f"{env_id}, the scripted expert, seeds 0..{args.episodes - 1}: {steps} steps in all "
        f"({steps / args.episodes:.1f} per episode); {os.cpu_count()} cores on this machine."
    )

    rate = report.table(
        ["Run", "Workers", "evaluate episodes/s", "collect episodes/s", "evaluate speed-up", "collect speed-up"],
        title="episodes per second (collect: episodes and the dataset written)",
    )
    rate.add(
        "one process, no Ray",
        "-",
        f"{args.episodes / evaluate_s:.1f}",
        f"{args.episodes / collect_s:.1f}",
        "1.00×",
        "1.00×",
    )
    costs = report.table(
        [
            "Workers",
            "Ray start s",
            "worker start-up s (import + first make), median",
            "make again s, median",
            "worker memory MB, median",
            "Ray's own processes MB",
        ],
        title="what each worker costs",
    )
    warm_one_worker = {}  # evaluate, collect episodes/s of one warm worker: what each further core adds at best
    worker_costs = {}
    for workers in args.workers:
        started, _ = _timed(lambda: ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False))
        try:
            probes = ray.get([_probe.remote(env_id) for _ in range(2 * workers)])
            startup = sorted(first for _, first, _ in probes)[len(probes) // 2]
            again = sorted(second for _, _, second in probes)[len(probes) // 2]
            for label in ("cold", "warm"):
                cold = label == "cold"
                repeats = 1 if cold else args.repeats
                _fresh_workers(workers, cold)
                spent, results = _best(
                    repeats, lambda: pool.run_episodes_on_ray([evaluation], seeds, workers, progress=False)[0]
                )
                assert results == reference, "the cluster's episodes differ from the single process's"
                _fresh_workers(workers, cold)
                spent_collect = _collect(env_id, args.episodes, pool.recorder(workers, progress=False), repeats)
                if workers == 1 and not cold:
                    warm_one_worker = {"evaluate": args.episodes / spent, "collect": args.episodes / spent_collect}
                rate.add(
                    label,
                    workers,
                    f"{args.episodes / spent:.1f}",
                    f"{args.episodes / spent_collect:.1f}",
                    f"{evaluate_s / spent:.2f}×",
                    f"{collect_s / spent_collect:.2f}×",
                )
            pids = sorted({pid for pid, _, _ in ray.get([_probe.remote(env_id) for _ in range(2 * workers)])})
            memory = sorted(rss_mb(pid) for pid in pids)
            worker_costs = {"startup": startup, "memory": memory[len(memory) // 2], "ray": _ray_processes_mb()}
            costs.add(
                workers,
                f"{started:.1f}",
                f"{startup:.1f}",
                f"{again:.2f}",
                f"{worker_costs['memory']:.0f}",
                f"{worker_costs['ray']:.0f}",
            )  # one reading serves the table and the projection
        finally:
            ray.shutdown()

    head = report.table(["per episode", "value"], title="what the head does per episode")
    head.add("recorded episode sent back (collect), pickled", f"{episode_bytes / 1024:.0f} KiB")
    head.add("writing the dataset (Minari, HDF5)", f"{1000 * write_s / args.episodes:.1f} ms")
    head.add("episode in one process (evaluate)", f"{1000 * evaluate_s / args.episodes:.1f} ms")
    _projection(
        report, args.cluster_cores, args.episodes / evaluate_s, write_s / args.episodes, warm_one_worker, worker_costs
    )
    report.finish()


def _projection(
    report: Report,
    cores: int,
    one_process_rate: float,
    write_s_per_episode: float,
    warm_one_worker: dict,
    worker_costs: dict,
) -> None:
    """A cluster of `cores` worker CPUs, one task per core, from the figures above. Evaluate's head only merges
    tables; collect's head also writes every episode into one dataset, one after another, so the rate at which
    it writes caps collect however many workers there are."""
    if not warm_one_worker or not worker_costs:
        return
    per_core = one_process_rate  # a core runs episodes as one process does; a warm worker pays Ray on top
    head_writes = 1 / write_s_per_episode
    table = report.table(["projection", "value"], title=f"projection to {cores} worker cores")
    table.add("evaluate episodes/s, every core as one process", f"{cores * per_core:.0f}")
    table.add("collect episodes/s the workers could record", f"{cores * per_core:.0f}")
    table.add("collect episodes/s the head can write (one dataset)", f"{head_writes:.0f}")
    table.add("collect: workers beyond which the head is the limit", f"{head_writes / per_core:.0f}")
    table.add("worker memory, all workers (GB)", f"{cores * worker_costs['memory'] / 1024:.1f}")
    table.add("worker start-up, each (import + first make, s)", f"{worker_costs['startup']:.1f}")
    table.add("Ray's own processes on the head (MB)", f"{worker_costs['ray']:.0f}")
    table.add("one warm Ray worker ÷ one process (evaluate)", f"{warm_one_worker['evaluate'] / per_core:.2f}×")


if __name__ == "__main__":
    main()
