"""`sim.fidelity: fast` on MuJoCo: which cycles need no dynamics, and where such a cycle ends.

A cycle is played one of four ways (the reference, `full`, always takes the last):
- at rest: arm, gripper and objects are still and every command is reached: nothing to simulate;
- kinematic: every object rests and the whole commanded motion of the arm's moving shapes and the gripper is
  proven NEAR_CONTACT away from each object's bounding sphere (the proof PyBullet's fast fidelity uses,
  envfactory/geometry/object_clearance.py): the arm is set on its target and the gripper where its drive
  takes it, without a substep;
- carried: an object held in a stable grasp rides with the hand while the motion is proven clear of every
  other shape (held.py);
- dynamic: the substeps of the commanded motion, then more in small chunks until arm, gripper and objects
  are at rest twice in a row; the rest of the cycle would hold still, so it is not simulated.
"""

from __future__ import annotations

from envfactory.backends.at_rest import GRIPPER_REST, JOINT_REST, OBJECT_REST, OBJECT_SPIN_REST

# The servos follow the profile's quintic with a lag of a few substeps; a cycle played kinematically must
# leave them this long after the profile ends, as the dynamic cycle would (the tracking test in
# tests/test_mujoco.py measures what remains).
SETTLE_TIME = 0.1
# Once the commanded motion is over, the rest test runs every this many substeps.
REST_CHECK_EVERY = 8


def objects_at_rest(data, object_dofs: dict[str, int]) -> bool:
    """Every object's free joint slower than the rest limits (linear, then angular: its six dofs), squared speeds
    against squared limits on plain floats: a test every cycle makes."""
    for dof in object_dofs.values():
        vx, vy, vz, wx, wy, wz = data.qvel[dof:dof + 6].tolist()
        # asked as "below the limits", so that a NaN (a blown-up state) is never taken for rest
        if not (vx * vx + vy * vy + vz * vz < OBJECT_REST ** 2 and wx * wx + wy * wy + wz * wz < OBJECT_SPIN_REST ** 2):
            return False
    return True


def robot_at_rest(data, arm_dof, gripper_dof: int | None) -> bool:
    """`arm_dof`: the arm's dof addresses (a slice or an index array)."""
    if gripper_dof is not None and not abs(data.qvel[gripper_dof]) < GRIPPER_REST:
        return False
    return all(abs(speed) < JOINT_REST for speed in data.qvel[arm_dof].tolist())  # a few numbers: plain floats
