"""What the env knows after a step, read once and shared by every term; and the physical changes that event
terms ask of a simulator."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class ObjectState:
    position: np.ndarray  # task frame
    rotation: np.ndarray
    rpy: np.ndarray
    linear_velocity: np.ndarray
    angular_velocity: np.ndarray
    joint: float = 0.0  # a fixture's joint past its lower limit (m); 0 for a free object
    joint_velocity: float = 0.0


@dataclass
class EnvState:
    joint_positions: np.ndarray  # /joint_states order
    joint_velocities: np.ndarray
    q_arm: np.ndarray  # action order
    gripper: float
    ee_position: np.ndarray  # task frame
    ee_rotation: np.ndarray
    ee_rpy: np.ndarray
    desired_goal: np.ndarray
    current_goal: np.ndarray  # the lift stage's goal while it lasts, else the desired goal
    previous_action: np.ndarray
    objects: dict[str, ObjectState] = field(default_factory=dict)

    def position_of(self, name: str) -> np.ndarray:
        """`ee` or an object's name: the point a goal term measures from."""
        return self.ee_position if name == "ee" else self.objects[name].position


@dataclass(frozen=True)
class PhysicsChange:
    """One sampled physical quantity (an event term's draw) for a simulator to set."""

    quantity: str  # one of PHYSICS_QUANTITIES
    target: str  # the object it belongs to; "" for the table, the arm or the gripper
    value: float  # in the quantity's unit: kg, a friction coefficient, N m s/rad, N


PHYSICS_QUANTITIES = ("object_mass", "object_friction", "table_friction", "arm_damping", "gripper_force")
