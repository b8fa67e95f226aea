"""Run episodes of an env with a policy and collect what the CLI reports."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterator

import numpy as np

from envfactory.backends.base import BackendError, MotionRefused


@dataclass(frozen=True)
class EpisodeResult:
    index: int
    seed: int
    episode_return: float
    length: int
    success: bool
    rejected: int
    abort_reason: str = ""  # why a fault ended the episode early (a real robot's stale feed, lost link...)
    first_success: int | None = None  # the step count at which is_success first held (None: never)


def iter_episodes(
    env,
    policy,
    episodes: int,
    seed: int,
    on_frame: Callable | None = None,
    on_step: Callable | None = None,
    stop_on_success: bool = True,
) -> Iterator[EpisodeResult]:
    """With `stop_on_success` (the default, which the experts' figures are measured with) the runner
    ends an episode at its first success, so lengths read as time-to-success; Dense envs do not
    terminate at the goal, so there it cuts short what a learner sees. Without it each episode ends
    where the env ends it (terminated or truncated), as a learner sees it (`envfactory run`,
    `collect`). `success` is is_success at the last step taken; `first_success` is the step count
    at which it first held, either way.

    A fault ends its episode (recorded with the reason) and the next reset
    recovers; a reset that cannot recover raises, after the episodes so far
    were yielded. A closed motion gate is not a fault: it ends the run."""
    for index in range(episodes):
        episode_seed = seed + index
        observation, info = env.reset(seed=episode_seed)
        if hasattr(policy, "reset"):
            policy.reset()
        if on_frame is not None:
            on_frame(env.render())
        total, length, rejected, success = 0.0, 0, 0, bool(info.get("is_success", False))
        first_success = 0 if success else None
        abort = ""
        while True:
            try:
                observation, reward, terminated, truncated, info = env.step(policy(observation))
            except MotionRefused:
                raise
            except BackendError as exc:  # the backend stopped the arm before it raised
                abort = str(exc)
                break
            total += float(reward)
            length += 1
            rejected += int(info.get("action_rejected", 0.0) > 0)
            success = bool(info.get("is_success", False))
            if success and first_success is None:
                first_success = length
            abort = info.get("abort_reason", "")
            if on_frame is not None:
                on_frame(env.render())
            if on_step is not None:
                on_step(info)
            if terminated or truncated or (stop_on_success and success):
                break
        yield EpisodeResult(index, episode_seed, total, length, success, rejected, abort, first_success)


def run_episodes(
    env,
    policy,
    episodes: int,
    seed: int,
    on_frame: Callable | None = None,
    on_step: Callable | None = None,
    stop_on_success: bool = True,
) -> list[EpisodeResult]:
    return list(iter_episodes(env, policy, episodes, seed, on_frame, on_step, stop_on_success))


def success_rate(results: list[EpisodeResult]) -> float:
    return float(np.mean([r.success for r in results])) if results else 0.0
