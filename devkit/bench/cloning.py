"""How much of the expert a plain clone keeps: an actor network trained on a demonstration dataset alone
(behaviour cloning, mean squared error on the recorded actions), then run deterministically on the learning
runs' evaluation seeds. It separates what the demonstrations can teach from what SAC + HER adds to it: a
run whose clone already fails learns its task from the critic, not from the demonstrations.

    python -m devkit.bench.cloning DATASET [DATASET ...] [--epochs 300] [--net-arch 256 256] [--episodes 50]

Each DATASET is a folder written by `envfactory collect` (or a Minari ID); its env is made with the kwargs it
was collected with. Observations go in as SB3's MultiInputPolicy flattens them (keys in sorted order).
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np
import torch

from envfactory.envs.episodes import run_episodes
from envfactory.learn.demo_replay import open_demonstrations
from envfactory.learn.loop import EVAL_SEED
from envfactory.registration import registry  # noqa: F401  (registers the IDs)


def flat(observation, keys: list[str]) -> np.ndarray:
    return np.concatenate([np.asarray(observation[k], np.float32).reshape(-1) for k in keys])


def training_rows(demonstrations, keys: list[str]) -> tuple[torch.Tensor, torch.Tensor]:
    """Every (observation, action) pair of the dataset: each episode's n + 1 observations less its last."""
    inputs = [
        np.concatenate(
            [np.asarray(e.observations[k][: len(e.actions)], np.float32).reshape(len(e.actions), -1) for k in keys],
            axis=1,
        )
        for e in demonstrations.episodes
    ]
    return torch.from_numpy(np.concatenate(inputs)), torch.from_numpy(
        np.concatenate([e.actions for e in demonstrations.episodes])
    )


def clone(inputs, actions, net_arch: list[int], epochs: int, seed: int) -> tuple[torch.nn.Module, float]:
    """An MLP with a tanh output (the actor's squashing) fitted to the actions; returns it and its final loss."""
    torch.manual_seed(seed)
    sizes = [inputs.shape[1], *net_arch]
    layers = [m for a, b in zip(sizes, sizes[1:]) for m in (torch.nn.Linear(a, b), torch.nn.ReLU())]
    net = torch.nn.Sequential(*layers, torch.nn.Linear(sizes[-1], actions.shape[1]), torch.nn.Tanh())
    optimizer = torch.optim.Adam(net.parameters(), 1e-3)
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, epochs)
    for _ in range(epochs):
        order = torch.randperm(len(inputs))
        for start in range(0, len(inputs), 256):
            batch = order[start : start + 256]
            loss = ((net(inputs[batch]) - actions[batch]) ** 2).sum(dim=1).mean()
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
        schedule.step()
    with torch.no_grad():
        return net, float(((net(inputs) - actions) ** 2).sum(dim=1).mean())


def evaluate(demonstrations, net, keys: list[str], episodes: int) -> tuple[float, int]:
    """Success rate on the evaluation seeds, and how many episodes end on a refused action."""
    env = gym.make(demonstrations.env_id, **demonstrations.env_kwargs)

    def policy(observation):
        with torch.no_grad():
            return net(torch.from_numpy(flat(observation, keys))[None])[0].numpy()

    last_steps = []

    def keep_last(info):
        last_steps.append(bool(info.get("action_rejected", 0.0)))

    try:
        ended_refused = 0
        results = []
        for index in range(episodes):
            last_steps.clear()
            results += run_episodes(env, policy, 1, EVAL_SEED + index, on_step=keep_last)
            ended_refused += int(last_steps[-1])
        return float(np.mean([r.success for r in results])), ended_refused
    finally:
        env.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("datasets", nargs="+")
    parser.add_argument("--epochs", type=int, default=300)
    parser.add_argument("--net-arch", type=int, nargs="+", default=[256, 256])
    parser.add_argument("--episodes", type=int, default=50)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    torch.set_num_threads(1)
    print("| dataset | env | noise | transitions | epochs | loss | success | ended on a refusal | time |")
    print("|---|---|---|---|---|---|---|---|---|")
    for reference in args.datasets:
        started = time.perf_counter()
        demonstrations = open_demonstrations(reference)
        keys = sorted(demonstrations.observation_space.spaces)
        inputs, actions = training_rows(demonstrations, keys)
        net, loss = clone(inputs, actions, args.net_arch, args.epochs, args.seed)
        success, refused = evaluate(demonstrations, net, keys, args.episodes)
        print(
            f"| {reference} | {demonstrations.env_id} | {demonstrations.action_noise:g} | {len(inputs):,} | "
            f"{args.epochs} | {loss:.4f} | {success:.0%} | {refused} of {args.episodes} | "
            f"{time.perf_counter() - started:.0f} s |",
            flush=True,
        )


if __name__ == "__main__":
    main()
