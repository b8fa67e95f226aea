from envfactory.backends.pybullet.backend import PyBulletBackend

__all__ = ["PyBulletBackend"]
