"""The queue's records and states: what a queued job is, whatever store keeps it.

A queued job is a **snapshot**: the job file's text, the device profile's text and
the plotter program built from them when the job was added (its text, sections,
pauses and SHA-256).  Editing the job file, its SVG files or the device profile
later changes nothing queued; the program is what runs.

States and transitions (every change is one transaction)::

    queued ──claim──> running ──pause──> waiting ──continue──> running
    running ──> done | failed | cancelled | interrupted
    waiting ──> cancelled | interrupted
    running/waiting, lease expired or worker process gone ──> interrupted
                                       (cancelled if a cancel was requested)
    interrupted ──claim──> running      (resumes from the last acknowledged byte)
    queued, interrupted ──cancel──> cancelled
    running, waiting ──cancel──> (cancel requested; the worker stops the plotter) cancelled
    failed, cancelled, interrupted ──retry──> queued   (a resume unless --restart or nothing
                                                       was acknowledged)

A worker holds a **lease** on its job and renews it (the heartbeat); a job whose
lease expired, or whose worker process on this machine is gone, becomes
interrupted at the next write to the queue.  Leases compare wall clocks, so hosts
that share a queue need synchronized clocks (NTP).  Claims are atomic: a job runs on one
worker, and a plotter (its port) runs one job at a time.  A plotter with an
interrupted job (a half-drawn sheet on it) runs nothing else until that job is
resumed, cancelled or removed; so does one with a job queued again to resume (``retry``
without ``restart`` of a job partly acknowledged), and such resumes are claimed first.

Every store (:mod:`foldfab.queue.sqlite`, :mod:`foldfab.queue.postgres`, both on the rules of
:mod:`foldfab.queue.sqlstore`) keeps these records and follows these transitions.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from foldfab.errors import FoldfabError
from foldfab.plotting.progress import done_share
from foldfab.queue.limits import MAX_PLOTTER_NAME
from foldfab.queue.snapshot import Snapshot



@dataclass(frozen=True)
class NewJob:
    """A snapshot to add ``copies`` times on ``port`` with ``priority``; ``plotter``: only for that
    registered plotter (its port, whatever ``port`` says); ``any_plotter``: for any plotter of the
    snapshot's profile (``port``, if any, is where a worker without a port of its own runs it)."""

    snapshot: Snapshot
    port: str
    priority: int = 0
    copies: int = 1
    plotter: str | None = None
    any_plotter: bool = False

    @classmethod
    def targeted(cls, snapshot: Snapshot, port: str | None, plotter: str | None, profile_port: str | None,
                 priority: int = 0, copies: int = 1) -> NewJob:
        """A job for the plotter named ``plotter``, else the one at ``port``, else (neither) any
        plotter of the snapshot's profile, which a worker without a port of its own runs at
        ``profile_port`` (the profile's).  The one rule of ``queue add`` and the studio."""
        return cls(snapshot, port or profile_port or "", priority, copies, plotter, not (port or plotter))

    def where(self) -> str:
        """Where the job runs, in words."""
        if self.plotter:
            return f"on plotter {self.plotter}"
        if not self.any_plotter:
            return f"at {self.port}"
        return (f"for any plotter of it (foldfab queue run --device {self.snapshot.device} --port PORT"
                + (f"; without --port: at {self.port})" if self.port else ")"))


@dataclass(frozen=True)
class JobRecord:
    """One job (one sheet) as the queue sees it."""

    id: int
    name: str
    job_path: str
    device: str
    port: str
    priority: int
    copy: int
    copies: int
    state: str
    created: float
    updated: float
    worker: str | None
    lease_expires: float | None
    acked_bytes: int
    program_bytes: int
    progress: str
    pauses_done: int
    cancel_requested: bool
    attempts: int
    reason: str | None
    drawn_mm: float
    """Length the plotter has drawn of the program's strokes (acknowledged)."""
    drawn_total_mm: float
    """Length of all the program's strokes; 0 until a worker has started the job."""
    plotter: str | None = None
    """The plotter the job is for (added or moved with ``--plotter``), or ran on (a registered one)."""
    any_plotter: bool = False
    """For any plotter of its profile, until one claims it."""

    @property
    def target(self) -> str:
        """Where the job runs, as listed: its plotter's name, ``any`` plotter of its profile, or its port."""
        return self.plotter or ("any" if self.any_plotter else self.port)

    @property
    def percent(self) -> float:
        """Share done, 0..100: of the drawn length, as ``foldfab plot`` shows it (of the bytes
        before a worker has measured it)."""
        return 100.0 * done_share(self.drawn_mm, self.drawn_total_mm, self.acked_bytes, self.program_bytes)

    def as_dict(self) -> dict:
        """Plain data for JSON output."""
        return {field: getattr(self, field) for field in self.__dataclass_fields__} | {
            "percent": round(self.percent, 1)}


@dataclass(frozen=True)
class PlotterRecord:
    """A plotter as its worker registered it, and what it does now."""

    name: str
    host: str
    port: str
    device: str | None
    """Its device profile; None: its worker was started without ``--device``."""
    worker: str
    started: float
    seen: float
    """Its worker's last heartbeat (wall clock)."""
    lease: float
    stopped: float | None
    """When its worker stopped cleanly; None while it runs."""
    offline_since: float | None
    """None while its worker runs; else when it stopped, or its last heartbeat (older than the lease)."""
    job: JobRecord | None
    """The job its worker holds (running or waiting at a pause)."""

    @property
    def state(self) -> str:
        """``offline``, ``paused`` (at a pause of its job: the flip of the sheet), ``drawing`` or ``idle``."""
        if self.offline_since is not None:
            return "offline"
        if self.job is not None:
            return "paused" if self.job.state == "waiting" else "drawing"
        return "idle"

    def as_dict(self) -> dict:
        """Plain data for JSON output."""
        fields = {name: getattr(self, name) for name in self.__dataclass_fields__ if name != "job"}
        return fields | {"state": self.state, "job": self.job.id if self.job else None,
                         "percent": round(self.job.percent, 1) if self.job else None}


def plotter_name(text: str) -> str:
    """``text`` if it can name a plotter (1 to :data:`MAX_PLOTTER_NAME` printable characters, no
    space at either end): names are listed on terminals and typed back; else FoldfabError."""
    if 0 < len(text) <= MAX_PLOTTER_NAME and text.isprintable() and text.strip() == text:
        return text
    shown = repr(text[:40]) + (f"... ({len(text)} characters)" if len(text) > 40 else "")
    raise FoldfabError(f"plotter name {shown}: expected 1 to {MAX_PLOTTER_NAME} printable characters (no control "
                       "characters, no space at either end), such as pi-a or cutter-2")


def default_plotter_name(host: str, port: str) -> str:
    """A worker's plotter name when it is given none: ``host:port``, unique in a farm."""
    return f"{host}:{port}"


@dataclass(frozen=True)
class Event:
    """One line of a job's log."""

    time: float
    kind: str
    message: str


@dataclass(frozen=True)
class WorkerId:
    """Who holds a lease: ``host/pid/token`` (the token tells threads of one process apart)."""

    host: str
    pid: int
    token: str

    @classmethod
    def current(cls) -> WorkerId:
        """A new identity for a worker in this process."""
        import secrets  # here: the command line's parser reads this module's limits (hmac, hashlib, socket: 50-150 ms)
        import socket

        return cls(socket.gethostname(), os.getpid(), secrets.token_hex(4))

    def __str__(self) -> str:
        return f"{self.host}/{self.pid}/{self.token}"


@dataclass(frozen=True)
class Claim:
    """A job a worker now holds: the record (state ``running``) and its snapshot."""

    job: JobRecord
    stored: Snapshot | None
    """The snapshot; None when it is damaged."""
    damage: str | None = None
    """Why the snapshot cannot be used (its program no longer matches its SHA-256)."""

    @property
    def snapshot(self) -> Snapshot:
        """The snapshot; FoldfabError (saying why) if it is damaged: the worker fails the job."""
        if self.stored is None:
            raise FoldfabError(self.damage or f"job {self.job.id}: no snapshot")
        return self.stored


@dataclass(frozen=True)
class Control:
    """What a heartbeat tells the worker: keep going, wait, stop or give up."""

    state: str
    cancel_requested: bool
    lost: bool
    """The job is no longer this worker's (its lease expired, or it was removed)."""


@dataclass(frozen=True)
class JobPage:
    """One page of a listing: jobs in id order, and how many more match after the last of them."""

    jobs: list[JobRecord]
    more: int
