"""The queue's states and limits, plain values: the command line's help names them, so this module
imports nothing (not :mod:`~foldfab.queue.records`, whose dataclasses cost start-up time)."""

STATES = ("queued", "running", "waiting", "done", "failed", "cancelled", "interrupted")
ACTIVE = ("running", "waiting")
RUNNABLE = ("queued", "interrupted")
FINISHED = ("done", "failed", "cancelled")
DEFAULT_LEASE = 30.0
DEFAULT_HEARTBEAT = 1.0
"""Longest time between a worker's heartbeats (seconds)."""
LEASE_HEARTBEATS = 5
"""A lease lasts at least this many heartbeat intervals: one late heartbeat (a busy queue file,
a slow disk) must not lose the job."""
MIN_LEASE = LEASE_HEARTBEATS * DEFAULT_HEARTBEAT
PRIORITIES = (-1000, 1000)
"""Lowest and highest priority (the command line and the studio)."""
MAX_COPIES = 1000
"""Most sheets of one job a single ``add`` queues."""
MAX_JOB_ID = 2 ** 63 - 1
"""The largest job id: the largest 64-bit signed integer, SQLite's and PostgreSQL's ``bigint``."""
MAX_PLOTTER_NAME = 200
"""Longest plotter name (the default, ``host:port``, holds a ``/dev/serial/by-id/...`` path)."""
DEFAULT_WAIT = 10.0
"""Seconds a queue store waits while another foldfab writes it."""
