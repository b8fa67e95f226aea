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


def _ee_link_rotation(env) -> np.ndarray:
    """The EE frame's rotation as PyBullet poses its link (independent of our kinematics)."""
    backend = env.unwrapped.backend
    names = {
        p.getJointInfo(backend.body, j, physicsClientId=backend.client)[12].decode(): j
        for j in range(p.getNumJoints(backend.body, physicsClientId=backend.client))
    }
    link = names[env.unwrapped.blueprint.spec.robot.ee_frame]
    quaternion = p.getLinkState(backend.body, link, physicsClientId=backend.client)[5]
    return np.array(p.getMatrixFromQuaternion(quaternion)).reshape(3, 3)


def _tool_axis_tilt(env) -> float:
    """Degrees between the tool's approach axis (the EE frame's x, per top_down_rpy [0, pi/2, 0]) and straight
    down, from PyBullet's link state of the EE frame's link."""
    x_axis = _ee_link_rotation(env)[:, 0]
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


@pytest.mark.parametrize("env_id", ["UR5eSlideSim-v0", "VX300SPushSim-v0"])
def test_the_yaw_row_turns_the_tool_about_the_vertical_by_its_step(env_id):
    """ee_yaw_action adds a Δyaw row; each action turns the EE about the vertical by delta_coeff times it, the
    EE staying where it is and the tool keeping its tilt. UR5e holds its orientation, the VX300S turns down
    first (top_down)."""
    env = gym.make(env_id, ee_action_type=True, ee_yaw_action=True)
    unwrapped = env.unwrapped
    try:
        layout = unwrapped.blueprint.action
        assert [row.label for row in layout.rows][:4] == ["Δx", "Δy", "Δz", "Δyaw"]
        assert env.action_space.shape == (layout.size,) and layout.rows[3].high == pytest.approx(np.pi)
        env.reset(seed=0)
        # over the task's object, where the VX300S can point its tool down
        ahead = next(iter(unwrapped.state.objects.values())).position + [0.0, 0.0, 0.12]

        def act(position, yaw_row):
            action = unwrapped.actions.hold_action(unwrapped.state)
            action[:3] = (position - unwrapped.state.ee_position) / layout.delta_coeff
            action[3] = yaw_row
            action = np.clip(action, env.action_space.low, env.action_space.high).astype(np.float32)
            info = env.step(action)[4]
            assert not info["action_rejected"], info["rejection_reason"]

        for _ in range(15):  # gets there (the VX300S turning down on the way)
            act(ahead, 0.0)
        for yaw_row in (2.0, 2.0, -1.0, -3.0):
            before, position = _ee_link_rotation(env), unwrapped.state.ee_position.copy()
            act(position, yaw_row)
            relative = _ee_link_rotation(env) @ before.T
            turn = np.degrees(np.arctan2(relative[1, 0], relative[0, 0]))
            assert turn == pytest.approx(np.degrees(yaw_row * layout.delta_coeff), abs=0.3), (yaw_row, turn)
            # about the vertical: the turn keeps the vertical where it was
            assert np.degrees(np.arccos(np.clip(relative[2, 2], -1, 1))) < 0.3
            assert np.linalg.norm(unwrapped.state.ee_position - position) < 0.002
    finally:
        env.close()


def test_a_yaw_row_without_delta_actions_is_refused():
    with pytest.raises(SpecError, match=r"env\.action\.yaw.*delta"):
        gym.make("UR5ePushSim-v0", ee_action_type=True, ee_yaw_action=True, delta_action=False)


def test_joint_mode_has_no_yaw_row():
    """The wrist turns through the joint rows: the flag leaves joint mode's layout as it was."""
    plain, flagged = gym.make("UR5ePushSim-v0"), gym.make("UR5ePushSim-v0", ee_yaw_action=True)
    try:
        assert plain.unwrapped.blueprint.action.rows == flagged.unwrapped.blueprint.action.rows
        assert not flagged.unwrapped.blueprint.action.yaw
    finally:
        plain.close(), flagged.close()


def test_a_turn_the_arm_cannot_make_in_a_step_is_flagged_not_dropped_silently():
    """With a step's joint change capped at 0.1 rad, a yaw row at π (0.157 rad of turn at delta_coeff 0.05)
    costs the UR5e's wrist more than a step allows: EE mode then solves for the position alone. The turn is
    not made (PyBullet's link pose) and the step says so in `action_out_of_bounds`; a turn within the cap is
    made and not flagged."""
    env = gym.make(
        "UR5eSlideSim-v0", ee_action_type=True, ee_yaw_action=True, overrides=["env.safety.max_joint_delta=0.1"]
    )
    unwrapped = env.unwrapped
    try:
        env.reset(seed=0)
        layout = unwrapped.blueprint.action
        for yaw_row, made in ((1.0, True), (np.pi, False)):
            before = _ee_link_rotation(env)
            action = unwrapped.actions.hold_action(unwrapped.state)
            action[3] = yaw_row
            info = env.step(action.astype(np.float32))[4]
            assert not info["action_rejected"], info["rejection_reason"]
            relative = _ee_link_rotation(env) @ before.T
            turn = float(np.arctan2(relative[1, 0], relative[0, 0]))
            if made:
                assert turn == pytest.approx(yaw_row * layout.delta_coeff, abs=0.005)
                assert info["action_out_of_bounds"] == 0.0
            else:
                assert abs(turn) < np.radians(1.0), np.degrees(turn)
                assert info["action_out_of_bounds"] == 1.0
    finally:
        env.close()
