"""The store interface: what every queue store does (:class:`QueueStore`) and the errors it raises.

Storage is behind :class:`QueueStore`; :class:`~foldfab.queue.sqlite.SqliteQueueStore` keeps it in an
SQLite file, :class:`~foldfab.queue.postgres.PostgresQueueStore` on a PostgreSQL server
(:func:`foldfab.queue.location.open_queue` chooses).  Every method is one atomic change (or one
consistent read).
"""

from __future__ import annotations

import threading
from typing import TYPE_CHECKING, Protocol, Sequence

from foldfab.errors import FoldfabError

if TYPE_CHECKING:
    from foldfab.queue.records import Claim, Control, Event, JobPage, JobRecord, NewJob, PlotterRecord, WorkerId
    from foldfab.queue.snapshot import Snapshot


class QueueStore(Protocol):
    """Where the queue lives.  Every method is one atomic change (or one consistent read)."""

    location: str
    survives_outages: bool
    """True: :class:`QueueBusy` means the store is out of reach for a while (a server restarting, the
    network gone), so a worker plots on and saves its progress once it is back; False: another
    writer holds the store, and a worker that cannot renew its lease in time stops."""

    def add(self, jobs: Sequence[NewJob]) -> list[int]:
        """Queue every copy of every job, all or nothing; the new ids in order."""

    def jobs(self, state: str | None = None) -> list[JobRecord]:
        """Jobs in id order (a dead worker's job already shows as interrupted)."""

    def page(self, state: str | None = None, after: int = 0, limit: int | None = None) -> JobPage:
        """Jobs with ids above ``after`` (in ``state``, as :meth:`jobs` sees it), at most ``limit``
        (None: all) in id order, and how many more there are (keyset paging: a page costs the
        same however deep it is)."""

    def job(self, job_id: int) -> JobRecord:
        """One job; FoldfabError if there is none."""

    def events(self, job_id: int) -> list[Event]:
        """The job's log, oldest first."""

    def snapshot(self, job_id: int) -> Snapshot:
        """The job's snapshot; FoldfabError if its program no longer matches its hash."""

    def cancel(self, job_id: int) -> JobRecord:
        """Cancel a job that has not run, or ask its worker to stop the plotter."""

    def retry(self, job_id: int, restart: bool = False, port: str | None = None,
              plotter: str | None = None) -> JobRecord:
        """Queue a failed, cancelled or interrupted job again (``restart``: from byte 0, a new sheet;
        ``port``: on another port, e.g. after the plotter came back as another device; ``plotter``:
        on that registered plotter of the job's profile, the operator moved the sheet there)."""

    def continue_job(self, job_id: int, source: str) -> JobRecord:
        """The operator acted at the pause (``source`` says where): ``waiting`` -> ``running``.
        The worker records the pauses confirmed (``pauses_done``) once it goes on."""

    def remove(self, job_id: int) -> None:
        """Delete a job that no worker holds, with its log."""

    def clear(self, states: Sequence[str]) -> int:
        """Delete every job in ``states``; how many."""

    def claim(self, worker: WorkerId, lease: float, device: str | None = None, port: str | None = None,
              exclude: Sequence[int] = (), plotter: str | None = None) -> Claim | None:
        """Atomically take the next runnable job (for ``device``/``port`` if given, not in ``exclude``;
        a worker with a ``port`` also takes the jobs for its ``plotter`` and for any plotter of its
        ``device``, and never one for another plotter).
        A job whose snapshot is damaged is claimed too: its :attr:`Claim.snapshot` raises, and the
        worker fails the job and reports it."""

    def runnable(self, device: str | None = None, port: str | None = None,
                 exclude: Sequence[int] = (), plotter: str | None = None) -> list[JobRecord]:
        """Jobs a claim would take, in claim order (without claiming them)."""

    def heartbeat(self, job_id: int, worker: WorkerId, lease: float, acked_bytes: int | None = None,
                  progress: str | None = None, pauses_done: int | None = None,
                  drawn: tuple[float, float] | None = None) -> Control:
        """Renew the lease, persist progress (``drawn``: mm drawn and in all), read cancel/continue requests."""

    def log(self, job_id: int, kind: str, message: str) -> None:
        """Add an event to the job's log."""

    def wait_at_pause(self, job_id: int, worker: WorkerId, message: str) -> Control:
        """``running`` -> ``waiting`` at a pause; log the operator's instruction."""

    def finish(self, job_id: int, worker: WorkerId, state: str, message: str,
               acked_bytes: int | None = None, pauses_done: int | None = None,
               progress: str | None = None, drawn: tuple[float, float] | None = None) -> bool:
        """End the worker's hold: ``done``, ``failed``, ``cancelled`` or ``interrupted``; False if it was lost."""

    def register_plotter(self, name: str, port: str, device: str | None, worker: WorkerId, lease: float) -> None:
        """``worker`` runs plotter ``name`` at ``port`` (of profile ``device``) from now on;
        FoldfabError if another worker that is online holds the name."""

    def plotter_alive(self, name: str, worker: WorkerId) -> bool:
        """An idle worker's heartbeat for its plotter (a job's heartbeat renews it too); False if the
        plotter is no longer this worker's."""

    def unregister_plotter(self, name: str, worker: WorkerId) -> None:
        """The worker stopped cleanly: its plotter is offline."""

    def plotters(self) -> list[PlotterRecord]:
        """Every registered plotter with what it does now (idle, drawing, paused, offline)."""

    def wait_for_work(self, timeout: float, stop: threading.Event) -> None:
        """Wait up to ``timeout`` s for a job to become runnable (sooner when the store can tell,
        as PostgreSQL's ``NOTIFY`` does), or until ``stop`` is set."""

    def close(self) -> None:
        """Release the storage."""


class QueueBusy(FoldfabError):
    """Another process held the queue's write lock for longer than the store waits: a passing
    condition (a worker's heartbeat tries again), unlike a full disk or a read-only file."""
