"""What "at rest" means to the engines' fast cycles, and how each cycle was played: shared by PyBullet's and
MuJoCo's fast fidelity, so one scene counts as resting, or not, on both."""

from __future__ import annotations

from dataclasses import dataclass

# At rest: joint speeds (rad/s, m/s for a finger), an object's linear (m/s) and angular (rad/s) speed.
# Under gravity an unsupported body gains 9.81 m/s² × dt (0.04 m/s at 240 Hz) in one substep.
JOINT_REST = 1e-3
# A gripper squeezing the cube creeps on below JOINT_REST for many cycles (measured ~1.4e-4 rad/s in
# a UR5e PnP carry): it counts as at rest only ten times slower, so the squeeze keeps its dynamics.
GRIPPER_REST = 1e-4
OBJECT_REST = 1e-3
OBJECT_SPIN_REST = 1e-2


@dataclass
class CycleCounts:
    """How the cycles were played: the benchmarks and the fidelity tests read these."""

    kinematic: int = 0
    at_rest: int = 0
    dynamic: int = 0
    carried: int = 0  # cycles in which a held object rode with the hand, no dynamics
    substeps: int = 0
