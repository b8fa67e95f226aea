"""Run episodes of an env with a policy and collect what the CLI reports."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np


@dataclass(frozen=True)
class EpisodeResult:
    index: int
    seed: int
    episode_return: float
    length: int
    success: bool
    rejected: int


def run_episodes(env, policy, episodes: int, seed: int, on_frame: Callable | None = None,
                 on_step: Callable | None = None, stop_on_success: bool = True) -> list[EpisodeResult]:
    """Dense envs do not terminate at the goal; with `stop_on_success` the runner
    ends a solved episode anyway, so lengths read as time-to-success."""
    results = []
    for index in range(episodes):
        episode_seed = seed + index
        observation, info = env.reset(seed=episode_seed)
        if hasattr(policy, "reset"):
            policy.reset()
        if on_frame is not None:
            on_frame(env.render())
        total, length, rejected, success = 0.0, 0, 0, bool(info.get("is_success", False))
        while True:
            observation, reward, terminated, truncated, info = env.step(policy(observation))
            total += float(reward)
            length += 1
            rejected += int(info.get("action_rejected", 0.0) > 0)
            success = bool(info.get("is_success", False))
            if on_frame is not None:
                on_frame(env.render())
            if on_step is not None:
                on_step()
            if terminated or truncated or (stop_on_success and success):
                break
        results.append(EpisodeResult(index, episode_seed, total, length, success, rejected))
    return results


def success_rate(results: list[EpisodeResult]) -> float:
    return float(np.mean([r.success for r in results])) if results else 0.0
