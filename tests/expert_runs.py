"""The scripted expert's episodes of one ID, run to the time limit: the tasks whose success is a state left
behind (a stack standing on its own, a cube turned and let go) count the last step, not the first success."""

import gymnasium as gym

from envfactory.envs.episodes import run_episodes
from envfactory.experts import make_policy


def full_episodes(env_id: str, episodes: int, seed: int = 0):
    env = gym.make(env_id)
    try:
        return run_episodes(env, make_policy("scripted", env), episodes=episodes, seed=seed, stop_on_success=False)
    finally:
        env.close()
