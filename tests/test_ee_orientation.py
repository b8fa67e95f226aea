"""EE mode on an arm whose home points the gripper forward: the robot YAML's `ee_mode_orientation: top_down`
turns the gripper straight down within a few steps and keeps it there while the EE moves; judged by
PyBullet's own pose of the EE link, not by our kinematics."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pybullet as p
import pytest

import envfactory  # noqa: F401  (registers the IDs)
from envfactory.schema.errors import SpecError


def _tool_axis_tilt(env) -> float:
    """Degrees between the tool's approach axis (the EE frame's x, per top_down_rpy [0, pi/2, 0]) and straight
    down, from PyBullet's link state of the EE frame's link."""
    backend = env.unwrapped.backend
    names = {
        p.getJointInfo(backend.body, j, physicsClientId=backend.client)[12].decode(): j
        for j in range(p.getNumJoints(backend.body, physicsClientId=backend.client))
    }
    link = names[env.unwrapped.blueprint.spec.robot.ee_frame]
    quaternion = p.getLinkState(backend.body, link, physicsClientId=backend.client)[5]
    x_axis = np.array(p.getMatrixFromQuaternion(quaternion)).reshape(3, 3)[:, 0]
    return float(np.degrees(np.arccos(np.clip(-x_axis[2], -1.0, 1.0))))


@pytest.mark.parametrize("env_id", ["VX300SPushSim-v0", "NED2PnPSim-v0"])
def test_ee_mode_turns_the_gripper_down_and_keeps_it_down(env_id):
    """From home the EE is moved over the cube, where pointing down is within reach (at the home position
    itself the arm cannot point the tool down), and then about there."""
    env = gym.make(env_id, ee_action_type=True)
    unwrapped = env.unwrapped
    try:
        env.reset(seed=0)
        assert _tool_axis_tilt(env) > 45.0  # home points the gripper forward
        over_cube = unwrapped.state.objects["cube"].position + [0.0, 0.0, 0.12]
        coefficient = unwrapped.blueprint.action.delta_coeff
        rng = np.random.default_rng(0)
        tilts = []
        for step in range(30):
            wanted = over_cube + (rng.uniform(-0.03, 0.03, 3) if step >= 15 else 0.0) - unwrapped.state.ee_position
            action = unwrapped.actions.hold_action(unwrapped.state)  # the gripper row, where there is one, holds
            action[:3] = wanted / coefficient
            action = np.clip(action, env.action_space.low, env.action_space.high).astype(np.float32)
            assert not env.step(action)[4]["action_rejected"]
            if step >= 15:
                tilts.append(_tool_axis_tilt(env))
        assert max(tilts) < 3.0, tilts
    finally:
        env.close()


def test_top_down_without_its_orientation_is_refused():
    with pytest.raises(SpecError, match="ee_mode_orientation"):
        gym.make("UR5eReacherSim-v0", overrides=["robot.ee_mode_orientation=top_down", "robot.top_down_rpy=null"])
