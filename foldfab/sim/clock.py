"""The simulators' virtual clock.

``real`` and ``fast`` tie virtual seconds to the wall clock (times 1, or times the
``speedup``), so everything a host does, computing and sleeping included, takes
virtual time.  ``instant`` moves only when a blocking host call moves it
(:meth:`Clock.sleep_until`): a long job runs as fast as Python can simulate it.
"""

from __future__ import annotations

import time

IDLE_WAIT = 0.05
"""Wall seconds a host call sleeps when nothing can change until another thread acts."""


class Clock:
    """Virtual seconds since the simulator started."""

    def __init__(self, mode: str, speedup: float = 50.0):
        self.mode = mode
        self.rate = {"real": 1.0, "fast": speedup}.get(mode)  # None: instant
        self._origin = time.monotonic()
        self._now = 0.0

    def now(self) -> float:
        if self.rate is None:
            return self._now
        return (time.monotonic() - self._origin) * self.rate

    def sleep_until(self, t: float) -> None:
        """Block until virtual time ``t`` (instant: jump there)."""
        if self.rate is None:
            self._now = max(self._now, t)
            return
        delay = (t - self.now()) / self.rate
        if delay > 0:
            time.sleep(delay)

    def wall(self, seconds: float) -> float:
        """Wall seconds that ``seconds`` of virtual time take (0 for instant)."""
        return 0.0 if self.rate is None else seconds / self.rate
