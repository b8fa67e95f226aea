"""What the robot tells the env on the real path: its joint states (the joints its driver publishes, matched by
name; the others read from the gripper's completed commands) and each task object's pose, brought into the task
frame, each held in a Feed with its staleness limit and its first fault."""

from __future__ import annotations

import threading
import time

import numpy as np

from envfactory.backends.base import BackendError
from envfactory.backends.rosbridge import messages
from envfactory.backends.rosbridge.feeds import Feed
from envfactory.backends.rosbridge.follow import FollowWatch
from envfactory.backends.rosbridge.gripper import GripperLink
from envfactory.backends.rosbridge.transforms import FrameGraph
from envfactory.schema.models import ComposedSpec


class Readings:
    def __init__(self, spec: ComposedSpec, lock: threading.Lock, follow: FollowWatch, gripper: GripperLink | None):
        robot, ros, real = spec.robot, spec.robot.ros, spec.env.real
        self.ros, self.follow, self.gripper = ros, follow, gripper
        self.state_names = robot.state_names
        self.arm_in_states = robot.arm_state_indices
        self.published = [i for i, entry in enumerate(robot.joint_states) if entry.published]
        self.published_names = [self.state_names[i] for i in self.published]
        self.unpublished = robot.unpublished_gripper_gains  # /joint_states index -> gain of the gripper value
        missing = [name for name in spec.task.objects if name not in ros.object_poses]
        if missing:
            raise BackendError(f"robot {robot.name!r}: ros.object_poses has no topic for {missing}")
        self.frames = FrameGraph(ros.task_frame_id, ros.static_transforms)
        target = spec.env.real.cube_tracker_target_frame
        if target and not ros.use_tf:
            try:
                self.frames.to_task(target, np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
            except KeyError as exc:
                raise BackendError(
                    f"cube_tracker_target_frame {target!r}: {exc.args[0]}; declare it in "
                    f"ros.static_transforms or set ros.use_tf"
                ) from None
        self.joints = Feed(ros.joint_states.topic, real.joint_state_timeout_s, lock)
        self.objects = {
            name: Feed(ros.object_poses[name].topic, real.cube_pose_timeout_s, lock) for name in spec.task.objects
        }

    @property
    def feeds(self) -> list[Feed]:
        return [self.joints, *self.objects.values()]

    def subscriptions(self) -> dict:
        """topic -> (type, callback) of everything read: joint states, object poses, /tf where used, and the
        gripper's action results."""
        ros = self.ros
        found = {ros.joint_states.topic: (ros.joint_states.type, self.on_joint_state)}
        for name in self.objects:
            topic = ros.object_poses[name]
            found[topic.topic] = (topic.type, lambda msg, name=name: self.on_pose(name, msg))
        if ros.use_tf:
            for name in ("/tf", "/tf_static"):
                found[name] = ("tf2_msgs/TFMessage", self.frames.learn)
        if self.gripper is not None and self.gripper.awaits_results:
            result = ros.gripper_command.result
            found[result.topic] = (result.type, self.gripper.on_result)
        return found

    def on_joint_state(self, msg: dict) -> None:
        try:
            published = messages.decode_joint_state(msg, self.published_names, self.ros.joint_states.template)
        except messages.MalformedMessage as exc:
            self.joints.fail(f"malformed message on {self.joints.topic}: {exc}")
            return
        position, velocity = np.zeros(len(self.state_names)), np.zeros(len(self.state_names))
        position[self.published], velocity[self.published] = published
        self.joints.update((position, velocity))
        self.follow.observe(position[self.arm_in_states], time.monotonic())

    def with_gripper_commands(self, position: np.ndarray) -> np.ndarray:
        """The joints the driver does not publish, read from the gripper's last completed command."""
        if self.unpublished:
            position = position.copy()
            value = self.gripper.completed if self.gripper is not None else 0.0
            for index, gain in self.unpublished.items():
                position[index] = gain * value
        return position

    def on_pose(self, name: str, msg: dict) -> None:
        feed = self.objects[name]
        try:
            frame, position, quaternion = messages.decode_pose(msg, self.ros.object_poses[name].template)
            position, quaternion = self.frames.to_task(frame, position, quaternion)
        except messages.MalformedMessage as exc:
            feed.fail(f"malformed message on {feed.topic}: {exc}")
            return
        except KeyError as exc:
            feed.fail(f"unusable pose on {feed.topic}: {exc.args[0]}")
            return
        feed.update((position, quaternion))
