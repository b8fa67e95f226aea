"""What the robot tells us: the newest good reading of each input topic, its local
receive time, and what went wrong since the fault was last cleared."""

from __future__ import annotations

import math
import threading
import time

from envfactory.backends.base import MalformedFeed, StaleFeed


def duration(seconds: float) -> str:
    return f"{seconds:.2f} s"


def beyond(age: float, limit: float) -> str:
    """An age past its limit, printed so that it reads as past it (rounded up, with a
    digit more when two decimals would print it equal to the limit)."""
    for digits in (2, 3, 4):
        scale = 10**digits
        shown = math.ceil(age * scale) / scale
        if shown > round(limit, digits):
            return f"{shown:.{digits}f} s old (limit {limit:.{digits}f} s)"
    return f"{age:.6f} s old (limit {limit:.6f} s)"


# How long a feed found past its limit is given to show a message that was already on its way (s)
RECEIVE_GRACE_S = 0.05


class Feed:
    def __init__(self, topic: str, limit: float, lock: threading.Lock):
        self.topic, self.limit = topic, limit
        self._lock = lock
        self.values: tuple | None = None
        self.received = -math.inf  # time.monotonic() at receipt
        self.error = ""

    def update(self, values: tuple) -> None:
        with self._lock:
            self.values, self.received = values, time.monotonic()

    def fail(self, reason: str) -> None:
        with self._lock:
            if not self.error:  # the first fault is the one to report
                self.error = reason

    def clear(self) -> float:
        """Forget the fault; returns the time, so a caller can wait for a reading newer than it."""
        with self._lock:
            self.error = ""
            return time.monotonic()

    def fresh(self) -> tuple[tuple, float]:
        """The newest values and their receive time, or the reason they cannot be trusted."""
        with self._lock:
            values, received, error = self.values, self.received, self.error
        if error:
            raise MalformedFeed(error)
        if values is None:
            raise StaleFeed(f"nothing received on {self.topic} yet")
        age = time.monotonic() - received
        if age > self.limit:
            # The receiving thread may only now get to run: a long computation of the caller's own (a motion
            # proof that holds the interpreter) kept it from taking messages already waiting on the socket, and
            # a feed is not stale for that. It is stale if nothing newer comes within a short grace.
            # What arrives in the grace may be a broken message: that, not the silence, is then the reason.
            deadline = time.monotonic() + RECEIVE_GRACE_S
            while time.monotonic() < deadline and not self.newer_than(received) and not self.error:
                time.sleep(RECEIVE_GRACE_S / 10)
            with self._lock:
                values, received, error = self.values, self.received, self.error
            if error:
                raise MalformedFeed(error)
            age = time.monotonic() - received
            if age > self.limit:
                raise StaleFeed(f"{self.topic} is stale: newest message {beyond(age, self.limit)}")
        return values, received

    def newer_than(self, since: float) -> bool:
        with self._lock:
            return self.values is not None and self.received > since
