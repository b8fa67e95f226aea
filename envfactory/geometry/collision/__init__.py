"""The robot's collision geometry, cut along its seams: the shapes and their fitted capsules and boxes
(shapes.py), what the shapes are to one another (structure.py), and the model that measures them at a pose
and over a motion (model.py)."""

from envfactory.geometry.collision.model import CollisionModel, MotionProof, PairRules
from envfactory.geometry.collision.shapes import Shape

__all__ = ["CollisionModel", "MotionProof", "PairRules", "Shape"]
