"""Render the picture the README and the docs home show: docs/img/scene.png.

The UR5e Push scene as `gym.make(ID, render_mode="rgb_array")` draws it, a few steps into an episode of the
task's scripted expert, so the arm stands over the table next to the cube instead of at its folded home.

    .venv/bin/python -m devkit.docs.render_scene                  # writes docs/img/scene.png
    .venv/bin/python -m devkit.docs.render_scene --id VX300SPnPSim-v0 --steps 4 --out /tmp/pnp.png
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import imageio.v3 as iio

import envfactory  # noqa: F401  (registers the IDs)
from envfactory.experts import make_policy

DEFAULT_OUT = Path(__file__).resolve().parents[2] / "docs" / "img" / "scene.png"


def render(env_id: str, steps: int, seed: int):
    """The env's rgb_array frame after `steps` steps of its scripted expert from the reset of `seed`."""
    env = gym.make(env_id, render_mode="rgb_array")
    try:
        observation, _ = env.reset(seed=seed)
        policy = make_policy("scripted", env)
        for _ in range(steps):
            observation, _, terminated, truncated, _ = env.step(policy(observation))
            if terminated or truncated:
                break
        return env.render()
    finally:
        env.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--id", default="UR5ePushSim-v0", help="a Sim ID (default: %(default)s)")
    parser.add_argument("--steps", type=int, default=6, help="expert steps before the frame (default: %(default)s)")
    parser.add_argument("--seed", type=int, default=0, help="reset seed (default: %(default)s)")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="PNG to write (default: docs/img/scene.png)")
    args = parser.parse_args()
    if args.steps < 0:
        parser.error("--steps must be 0 or more")
    if not args.out.parent.is_dir():
        parser.error(f"--out: folder {args.out.parent} does not exist")
    frame = render(args.id, args.steps, args.seed)
    iio.imwrite(args.out, frame, optimize=True)
    print(f"{args.out}: {frame.shape[1]}x{frame.shape[0]}, {args.out.stat().st_size // 1024} KB")


if __name__ == "__main__":
    main()
