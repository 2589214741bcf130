"""The clocks a live session runs on: the machine's monotonic clock, or a virtual one for tests.

A clock gives ``now()`` in seconds and ``sleep_until(t)``; the virtual clock jumps to ``t`` at
once, so that a test plays a minute of music at "real-time pace" in a fraction of a second and
every timing figure is exact.
"""

from __future__ import annotations

import time


class MonotonicClock:
    """``time.monotonic``: seconds since an arbitrary start, never going back."""

    def now(self) -> float:
        return time.monotonic()

    def sleep_until(self, t: float) -> None:
        wait = t - time.monotonic()
        if wait > 0:
            time.sleep(wait)


class VirtualClock:
    """A clock that only moves when told: ``sleep_until`` sets it, ``advance`` adds to it."""

    def __init__(self, start: float = 0.0):
        self.t = float(start)

    def now(self) -> float:
        return self.t

    def sleep_until(self, t: float) -> None:
        self.t = max(self.t, float(t))

    def advance(self, seconds: float) -> None:
        self.t += float(seconds)
