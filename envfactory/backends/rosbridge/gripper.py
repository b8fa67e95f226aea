"""The gripper on the real path: commands in the driver's units, sent only when they change, an action
goal's outcome read, and what the gripper reads where the driver publishes no joint for it.

A driver that runs one goal at a time (Niryo's tools commander) queues every goal it is sent and spends about
half a second on each after the jaws stop: a goal per step would pile up and a late close would run seconds
late. So a command goes out only when it differs from the last one sent, a step waits for its goal's result,
and a goal that does not succeed ends the episode with the driver's own words.
"""

from __future__ import annotations

import threading

from envfactory.backends.base import EpisodeAbort
from envfactory.backends.rosbridge import messages
from envfactory.schema.models import GripperCommand, GripperSpec

SAME_VALUE = 1e-6  # a position command closer than this (joint units) to the last one sent changes nothing


class GripperFailed(EpisodeAbort):
    """The driver did not carry out a gripper goal: it said so, or said nothing in time."""


class GripperLink:
    def __init__(self, command: GripperCommand, gripper: GripperSpec, assumed: float):
        self.command, self.gripper = command, gripper
        self.topic = command.topic
        self._lock = threading.Lock()
        self._sent: tuple | None = None  # what the driver was last asked for (its state, or its value)
        self._pending: tuple[str, float, float] | None = None  # (goal id, value, sent at) awaiting its result
        self._failure = ""
        # The gripper's value as far as commands are known to have completed; before the first, the value
        # the safety proof assumes (a gripper left as it is may be anywhere: open is the widest)
        self.completed = assumed

    @property
    def awaits_results(self) -> bool:
        return self.command.result is not None

    def message(self, value: float, now: float) -> dict | None:
        """The message for `value`, or None when the driver was already asked for the same."""
        state = messages.gripper_state(self.command, value, self.gripper.open, self.gripper.closed)
        asked = (state,) if state is not None else (round(value / SAME_VALUE),)
        if asked == self._sent:
            return None
        goal_id = messages.new_goal_id()
        msg = messages.encode_gripper(self.command, value, self.gripper.open, self.gripper.closed, goal_id)
        end = (
            value
            if state is None
            else (self.gripper.closed if state == self.command.states.closed else self.gripper.open)
        )
        with self._lock:
            self._sent = asked
            if self.awaits_results:
                self._pending = (goal_id, end, now)
            else:
                self.completed = end
        return msg

    def on_result(self, msg: dict) -> None:
        """A result on the action server's result topic (any client's goal: only ours counts)."""
        try:
            goal_id, status, said = messages.decode_action_result(msg)
        except messages.MalformedMessage as exc:
            with self._lock:
                self._failure = self._failure or f"malformed message on {self.command.result.topic}: {exc}"
            return
        with self._lock:
            if self._pending is None or goal_id != self._pending[0]:
                return
            _, end, _ = self._pending
            self._pending = None
            if status == messages.SUCCEEDED:
                self.completed = end
            else:
                self._sent = None  # the driver's state is unknown: the next command goes out whatever it is
                self._failure = self._failure or (
                    f"the gripper goal on {self.topic} ended {messages.GOAL_STATUS.get(status, status)}: {said}"
                )

    def busy(self, now: float) -> bool:
        """Whether a goal still awaits its result; GripperFailed if one failed or is overdue."""
        with self._lock:
            failure, pending = self._failure, self._pending
        if failure:
            raise GripperFailed(failure)
        if pending is None:
            return False
        if now - pending[2] > self.command.result.within_s:
            self.forget()
            raise GripperFailed(
                f"no result for the gripper goal on {self.topic} within "
                f"{self.command.result.within_s:.2f} s (on {self.command.result.topic})"
            )
        return True

    def forget(self) -> None:
        """After a fault or a reconnection: nothing is known to be pending or already asked for."""
        with self._lock:
            self._sent = self._pending = None
            self._failure = ""
