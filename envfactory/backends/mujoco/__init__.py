"""The MuJoCo engine: the same scene, robot and objects as PyBullet's, from the same specs."""

from envfactory.backends.mujoco.backend import MujocoBackend

__all__ = ["MujocoBackend"]
