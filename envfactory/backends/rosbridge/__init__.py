from envfactory.backends.rosbridge.backend import RosbridgeBackend

__all__ = ["RosbridgeBackend"]
