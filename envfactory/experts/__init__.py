"""Scripted experts that act through the env's own action space.

They plan with the env's kinematics (IK inside the policy) and emit the
action a learner would, so their episodes double as demonstrations. A task
names its expert and the expert's params in YAML; robot-specific numbers
(heights, offsets) are set per family in specs/.
"""

from __future__ import annotations

from envfactory.experts.drawer import DrawerExpert
from envfactory.experts.flip import FlipExpert
from envfactory.experts.pnp import PickPlaceExpert
from envfactory.experts.push import PushExpert
from envfactory.experts.reach import ReachExpert
from envfactory.experts.slide import SlideExpert
from envfactory.experts.stack import StackExpert

EXPERTS = {
    "reach": ReachExpert,
    "push": PushExpert,
    "pnp": PickPlaceExpert,
    "slide": SlideExpert,
    "stack": StackExpert,
    "flip": FlipExpert,
    "drawer": DrawerExpert,
}


class RandomPolicy:
    def __init__(self, env):
        self.space = env.action_space

    def reset(self) -> None:
        pass

    def __call__(self, observation):
        return self.space.sample()


def make_policy(kind: str, env, seed: int | None = None):
    """`seed` seeds the random policy's samples (default: from the env's generator)."""
    if kind == "random":
        env.action_space.seed(seed if seed is not None else int(env.unwrapped.np_random.integers(2**31)))
        return RandomPolicy(env)
    if kind != "scripted":
        raise ValueError(f"unknown policy {kind!r}: use 'random' or 'scripted'")
    task = env.unwrapped.blueprint.spec.task
    if task.expert is None or task.expert.policy not in EXPERTS:
        raise ValueError(f"task {task.name!r} has no scripted expert (known experts: {', '.join(EXPERTS)})")
    expert = EXPERTS[task.expert.policy]
    return expert(env.unwrapped, expert.Params.model_validate(task.expert.params))
