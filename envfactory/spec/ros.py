"""A robot's topics under rosbridge; every one can be overridden in YAML or by kwarg."""

from __future__ import annotations

from typing import Literal

from envfactory.spec.base import Model, Position, Rpy


class RosTopic(Model):
    topic: str
    type: str


class ArmCommand(RosTopic):
    # joint_trajectory: trajectory_msgs/JointTrajectory, one point at time_from_start (ur_robot_driver)
    # joint_group: interbotix_xs_msgs/JointGroupCommand {name: group, cmd: positions} (xs_sdk)
    encoding: Literal["joint_trajectory", "joint_group"]
    group: str = "arm"


class GripperCommand(RosTopic):
    # float64_array: std_msgs/Float64MultiArray with the one driven value (the Robotiq knuckle)
    # joint_single: interbotix_xs_msgs/JointSingleCommand {name, cmd} (xs_sdk gripper in linear_position mode)
    encoding: Literal["float64_array", "joint_single"]
    name: str = "gripper"


class StaticTransform(Model):
    """Where a frame sits in its parent: lets object poses from a camera reach the task frame."""

    parent: str
    xyz: Position = (0.0, 0.0, 0.0)
    rpy: Rpy = (0.0, 0.0, 0.0)


class RosSpec(Model):
    joint_states: RosTopic
    arm_command: ArmCommand
    gripper_command: GripperCommand | None = None
    object_poses: dict[str, RosTopic] = {}  # object name -> geometry_msgs/PoseStamped topic
    task_frame_id: str  # the ROS frame of the task frame (goals and observations)
    static_transforms: dict[str, StaticTransform] = {}  # frame -> its pose in the parent frame
    use_tf: bool = False  # also learn transforms from /tf and /tf_static
