"""The follow watchdog: an arm sent somewhere must start moving soon.

A command can go nowhere with no error anywhere: a topic whose subscriber has
another type (the server refuses it only in its own log), a controller that is
not running. The joint states then keep saying the arm stands still. Once a
command asks for a real move, the arm has the time its driver was given for
that move plus `timeout` seconds to move at least MIN_MOTION on some joint;
otherwise the episode ends with CommandIgnored. Judged against the driver's
own time, a small command under a long profile is no fault, and a controller
that executes nothing is still caught.
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
        self._allowed = 0.0  # how long its driver was given for it, plus the timeout
        self._start: np.ndarray | None = None
        # from a command that asks for motion to the first reading that shows it: the command latency the real
        # path has (transport both ways and the controller's start), what a sensing spec's action_delay models
        self.latencies: list[float] = []

    def commanded(self, q_now: np.ndarray, q_target: np.ndarray, now: float, length_s: float = 0.0) -> None:
        """A command went out, for the driver to carry out over `length_s`. The clock starts at the first one
        that asks for motion and keeps running through later ones until the arm moves, so a stream of commands
        cannot hide it."""
        if np.max(np.abs(np.asarray(q_target) - q_now)) < 2 * MIN_MOTION:
            return
        with self._lock:
            if self._since is None:
                self._since, self._start = now, np.array(q_now, float)
                self._allowed = length_s + self.timeout

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
            since, allowed = self._since, self._allowed
        if since is not None and now - since > allowed:
            raise CommandIgnored(
                f"the arm did not follow the command on {self.topic}: no joint moved {MIN_MOTION} rad within "
                f"{duration(allowed)} (the {duration(allowed - self.timeout)} its driver was given, plus "
                f"{duration(self.timeout)}). Nothing executes the commands (a controller that is not running, or a "
                f"topic the server refuses for its type)."
            )

    def clear(self) -> None:
        with self._lock:
            self._since = self._start = None
