"""Scripted experts that act through the env's own action space.

They plan with the env's kinematics (IK inside the policy) and emit the
action a learner would, so their episodes double as demonstrations.
"""

from __future__ import annotations

import numpy as np


class ReachExpert:
    """Steer the EE straight at the goal: IK in joint mode, Δ position in EE mode."""

    def __init__(self, env):
        self.env = env.unwrapped

    def __call__(self, observation) -> np.ndarray:
        env = self.env
        state, goal, layout = env.state, env.goal, env.blueprint.action
        low, high = layout.low, layout.high
        if layout.ee:
            wanted = (goal - state.ee_position) / layout.delta_coeff if layout.delta else goal
        else:
            solution = env.kinematics.solve_ik(state.q_arm, goal, gripper=state.gripper)
            wanted = (solution.q_arm - state.q_arm) / layout.delta_coeff if layout.delta else solution.q_arm
        if layout.delta:
            wanted = _shrink_into(wanted, low[: wanted.size], high[: wanted.size])
        if layout.gripper_in_action:
            wanted = np.append(wanted, env.blueprint.spec.robot.gripper.open)
        return np.clip(wanted, low, high).astype(np.float32)


def _shrink_into(vector: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Scale a step down uniformly so it fits the box, keeping its direction."""
    limit = np.where(vector >= 0, high, -low)
    ratio = np.max(np.abs(vector) / np.maximum(limit, 1e-9))
    return vector / ratio if ratio > 1.0 else vector


class RandomPolicy:
    def __init__(self, env):
        self.space = env.action_space

    def __call__(self, observation) -> np.ndarray:
        return self.space.sample()


EXPERTS = {"reach": ReachExpert}


def make_policy(kind: str, env):
    if kind == "random":
        env.action_space.seed(int(env.unwrapped.np_random.integers(2**31)))
        return RandomPolicy(env)
    if kind != "scripted":
        raise ValueError(f"unknown policy {kind!r}: use 'random' or 'scripted'")
    expert = env.unwrapped.blueprint.spec.task.expert
    if expert is None or expert not in EXPERTS:
        raise ValueError(f"task {env.unwrapped.blueprint.spec.task.name!r} has no scripted expert "
                         f"(known experts: {', '.join(EXPERTS)})")
    return EXPERTS[expert](env)
