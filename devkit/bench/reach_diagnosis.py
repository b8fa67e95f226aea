"""What a learner meets on a Reach goal env, measured without training.

    python -m devkit.bench.reach_diagnosis [--ids ID ...] [--goals N] [--steps N] [--episodes N] [-k name=value ...]

Per ID (kwargs apply to every env made, e.g. -k normalize_actions=true):
- goal box: the share of uniform goals reachable from the start pose (IK from
  home; the solved pose clear of the scene; the straight joint path from home clear);
- random actions: the share the safety check refuses, why, and what a refusal
  does (the arm holds: the largest joint change over a refused step); how far
  an accepted random step moves the EE, against the goal tolerance;
- observation scales: per column, the spread a random policy produces against
  the declared bound's width;
- pushing one way: a constant saturated action per direction, the share of steps refused
  (an unreachable target is refused and the arm holds: a learner that pushes past
  the arm's reach stays where it is);
- episode length: the scripted expert's steps to success against max_episode_steps.
"""

from __future__ import annotations

import argparse
from collections import Counter

import gymnasium as gym
import numpy as np

import envfactory  # noqa: F401  (registers the IDs)
from devkit.kwarg_option import add_kwarg_option, kwargs_from
from envfactory.envs.episodes import run_episodes
from envfactory.experts import make_policy

IDS = ["UR5eReacherGoalSim-v0", "VX300SReacherGoalSim-v0"]


def goal_box_reach(env, goals: int, rng) -> dict:
    u = env.unwrapped
    sampler = u.goals
    ik = pose = path = 0
    for goal in rng.uniform(sampler.low, sampler.high, (goals, 3)):
        solution = u.kinematics.solve_ik(u.home, goal, gripper=sampler.gripper)
        if not solution.success:
            continue
        ik += 1
        if not u.safety.pose_is_clear(solution.q_arm, sampler.gripper):
            continue
        pose += 1
        path += bool(u.safety.path_is_clear(u.home, solution.q_arm, sampler.gripper).accepted)
    return {"ik": ik / goals, "pose_clear": pose / goals, "path_clear": path / goals}


def random_steps(env, steps: int, seed: int) -> dict:
    u = env.unwrapped
    env.action_space.seed(seed)
    observation, _ = env.reset(seed=seed)
    vectors, reasons = [], Counter()
    refused = refused_move = 0
    moves = []
    for _ in range(steps):
        before, ee_before = u.state.q_arm.copy(), u.state.ee_position.copy()
        observation, _, terminated, truncated, info = env.step(env.action_space.sample())
        vectors.append(observation["observation"])
        if not info["action_rejected"]:
            moves.append(float(np.linalg.norm(u.state.ee_position - ee_before)))
        if info["action_rejected"]:
            refused += 1
            reasons[info["rejection_reason"].split(":")[0][:60]] += 1
            refused_move = max(refused_move, float(np.max(np.abs(u.state.q_arm - before))))
        if terminated or truncated:
            env.reset()
    vectors = np.array(vectors)
    space = env.observation_space["observation"]
    return {
        "refused": refused / steps,
        "ee_move": np.percentile(moves, [50, 90]),
        "reasons": reasons.most_common(4),
        "refused_max_joint_change": refused_move,
        "min": vectors.min(0),
        "max": vectors.max(0),
        "std": vectors.std(0),
        "width": space.high - space.low,
        "slots": u.observations.slots,
    }


def pushing(env, steps: int = 100) -> dict:
    """A policy that keeps pushing one way (as a saturated learner does): for each of the 26
    directions of {-1, 0, 1}^n (first three rows, the rest 0), `steps` steps from the start pose.
    An unreachable target is refused and the arm holds, so a push past the arm's reach stays refused."""
    import itertools

    size = env.action_space.shape[0]
    refused = clipped = stuck = 0
    directions = [d for d in itertools.product([-1.0, 0.0, 1.0], repeat=3) if any(d)]
    for direction in directions:
        action = np.zeros(size, np.float32)
        action[:3] = np.array(direction) * env.action_space.high[:3]
        env.reset(seed=0)
        last = False
        for _ in range(steps):
            _, _, terminated, truncated, info = env.step(action)
            last = info["action_rejected"] > 0
            refused += last
            clipped += info["action_out_of_bounds"] > 0
            if terminated or truncated:
                break
        stuck += last
    total = len(directions) * steps
    return {"refused": refused / total, "clipped": clipped / total, "stuck": stuck, "directions": len(directions)}


def expert_lengths(env, episodes: int) -> dict:
    results = run_episodes(env, make_policy("scripted", env), episodes=episodes, seed=100)
    lengths = np.array([r.length for r in results if r.success])
    return {
        "success": float(np.mean([r.success for r in results])),
        "mean": float(lengths.mean()),
        "median": float(np.median(lengths)),
        "max": int(lengths.max()),
        "limit": env.unwrapped.blueprint.max_episode_steps,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--ids", nargs="+", default=IDS)
    parser.add_argument("--goals", type=int, default=1000)
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--episodes", type=int, default=50)
    add_kwarg_option(parser)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    for env_id in args.ids:
        env = gym.make(env_id, **kwargs_from(args.kwarg))
        print(f"== {env_id} {args.kwarg or ''}")
        reach = goal_box_reach(env, args.goals, rng)
        print(
            f"goal box from the start pose ({args.goals} uniform goals): IK {reach['ik']:.1%}, "
            f"pose clear {reach['pose_clear']:.1%}, straight joint path clear {reach['path_clear']:.1%}"
        )
        steps = random_steps(env, args.steps, seed=0)
        print(
            f"random actions ({args.steps} steps): refused {steps['refused']:.1%}; "
            f"largest joint change over a refused step {steps['refused_max_joint_change']:.4f} rad"
        )
        print(
            f"    EE moves per accepted random step: median {steps['ee_move'][0]:.3f} m, "
            f"90th percentile {steps['ee_move'][1]:.3f} m (goal tolerance "
            f"{env.unwrapped.blueprint.spec.task.goal.tolerance:g} m)"
        )
        for reason, count in steps["reasons"]:
            print(f"    {count:5d} × {reason}")
        print("observation columns: slot[i]  random min..max  std  declared width  std/width")
        for slot in steps["slots"]:
            for i in range(slot.start, slot.stop):
                print(
                    f"    {slot.name}[{i - slot.start}]  {steps['min'][i]:+.3f}..{steps['max'][i]:+.3f}  "
                    f"{steps['std'][i]:.3f}  {steps['width'][i]:.3f}  {steps['std'][i] / steps['width'][i]:.3f}"
                )
        push = pushing(env)
        print(
            f"pushing one way for 100 steps (26 directions): {push['refused']:.0%} of steps refused, "
            f"{push['clipped']:.0%} clipped to the action box; {push['stuck']} of {push['directions']} "
            f"directions end refused"
        )
        lengths = expert_lengths(env, args.episodes)
        print(
            f"scripted expert ({args.episodes} episodes): success {lengths['success']:.0%}, steps to success "
            f"mean {lengths['mean']:.1f}, median {lengths['median']:.0f}, max {lengths['max']}; "
            f"episode limit {lengths['limit']}"
        )
        env.close()


if __name__ == "__main__":
    main()
