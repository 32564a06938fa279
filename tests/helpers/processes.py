"""Helpers for tests that drive foldfab in a subprocess: wait for events, never for a time."""

from __future__ import annotations

import subprocess
import time
from pathlib import Path


def wait_for_handler(proc: subprocess.Popen, sig: int, timeout: float = 120.0) -> None:
    """Wait until ``proc`` catches ``sig`` (its bit in SigCgt of /proc/PID/status): foldfab plot and
    queue run install their handlers first, before the heavy imports, so they are still starting."""
    deadline = time.monotonic() + timeout
    while True:
        status = Path(f"/proc/{proc.pid}/status").read_text()
        caught = int(next(line.split()[1] for line in status.splitlines() if line.startswith("SigCgt:")), 16)
        if caught >> (sig - 1) & 1:
            return
        assert proc.poll() is None and time.monotonic() < deadline, "foldfab never installed its handlers"
        time.sleep(0.002)  # poll interval


def wait_for(condition, timeout: float = 120.0) -> None:
    """Wait until ``condition()`` holds (a state the test waits for, never a time); fail after ``timeout`` s."""
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.02)  # poll interval
