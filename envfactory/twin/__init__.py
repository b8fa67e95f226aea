"""The digital twin: a PyBullet robot and cube behind a rosbridge-protocol server (server.py), playing the
robot's driver as its maker publishes it (drivers.py); twin.py holds the Twin that joins them."""

from envfactory.twin.server import Faults, Received
from envfactory.twin.twin import Twin

__all__ = ["Faults", "Received", "Twin"]
