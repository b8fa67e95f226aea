"""The follow watchdog: an arm sent somewhere must start moving soon.

A command can go nowhere with no error anywhere: a topic whose subscriber has
another type (the server refuses it only in its own log), a controller that is
not running. The joint states then keep saying the arm stands still. Once a
command asks for a real move, the arm has `timeout` seconds to move at least
MIN_MOTION on some joint; otherwise the episode ends with CommandIgnored.
"""

from __future__ import annotations

import threading

import numpy as np

from envfactory.backends.base import CommandIgnored
from envfactory.backends.rosbridge.feeds import duration

MIN_MOTION = 0.005  # rad: well above joint-state noise, well below any commanded move


class FollowWatch:
    def __init__(self, topic: str, timeout: float):
        self.topic, self.timeout = topic, timeout
        self._lock = threading.Lock()
        self._since: float | None = None  # when the unanswered command went out
        self._start: np.ndarray | None = None
        # from a command that asks for motion to the first reading that shows it: the command latency the real
        # path has (transport both ways and the controller's start), what a sensing spec's action_delay models
        self.latencies: list[float] = []

    def commanded(self, q_now: np.ndarray, q_target: np.ndarray, now: float) -> None:
        """A command went out. The clock starts at the first one that asks for motion and keeps
        running through later ones until the arm moves, so a stream of commands cannot hide it."""
        if np.max(np.abs(np.asarray(q_target) - q_now)) < 2 * MIN_MOTION:
            return
        with self._lock:
            if self._since is None:
                self._since, self._start = now, np.array(q_now, float)

    def observe(self, q_arm: np.ndarray, now: float) -> None:
        """A joint reading arrived, at `now`: a first motion since a command times the command's latency."""
        with self._lock:
            if self._start is not None and np.max(np.abs(q_arm - self._start)) >= MIN_MOTION:
                if now > self._since:  # a reading taken before the command went out times nothing
                    self.latencies.append(now - self._since)
                self._since = self._start = None

    def take_latencies(self) -> list[float]:
        """The command-to-motion times measured since the last call (seconds)."""
        with self._lock:
            taken, self.latencies = self.latencies, []
        return taken

    def check(self, now: float) -> None:
        with self._lock:
            since = self._since
        if since is not None and now - since > self.timeout:
            raise CommandIgnored(
                f"the arm did not follow the command on {self.topic}: no joint moved {MIN_MOTION} rad within "
                f"{duration(self.timeout)}. Nothing executes the commands (a controller that is not running, or a "
                f"topic the server refuses for its type).")

    def clear(self) -> None:
        with self._lock:
            self._since = self._start = None
