"""The queue's registry of plotters: :class:`PlotterRegistry`, a part of every SQL store.

A worker with a port of its own (``foldfab queue run --port PORT``) registers its plotter when it
starts: a name (``--name``, default ``host:port``), its host, its port and its device profile
(``--device``).  Its heartbeats (while it draws and while it waits for jobs) keep the plotter
online; a clean exit marks it offline at once, and one whose last heartbeat is older than its
lease (the host lost power or its network), or whose worker process on this host is gone, is
listed offline since that heartbeat.  A name is held by one running worker at a time: another
worker may take it only once that one is offline.

Jobs name a registered plotter with ``--plotter`` (:meth:`PlotterRegistry._plotter` finds it and
checks its profile).  The methods run on the transactions of
:class:`~foldfab.queue.sqlstore.SqlQueueStore`.  Standard library only (``foldfab queue plotters``
imports it).
"""

from __future__ import annotations

import math
import time
from contextlib import AbstractContextManager
from typing import Any, Callable

from foldfab.errors import FoldfabError
from foldfab.queue.records import JobRecord, PlotterRecord, WorkerId, plotter_name

_COLUMNS = "name, host, port, device, worker, worker_pid, started, seen, lease, stopped"


class PlotterRegistry:
    """Registering, renewing, signing off and listing plotters (see the module docstring)."""

    location: str
    _host: str
    _read: Callable[[], AbstractContextManager[Any]]
    _write: Callable[..., AbstractContextManager[Any]]
    _exists: Callable[[], bool]

    def _held_jobs(self, db: Any) -> dict[str, JobRecord]:
        """The running and waiting jobs, by the worker that holds each."""
        raise NotImplementedError

    def _process_gone(self, host: str, pid: int) -> bool:
        """Whether process ``pid`` of ``host`` is known to be gone (it ran on this host)."""
        raise NotImplementedError

    def _offline_since(self, row: tuple, now: float) -> float | None:
        """When the plotter of ``row`` (:data:`_COLUMNS`, checked by :func:`_checked`) went offline;
        None if its worker runs."""
        host, pid, seen, lease, stopped = row[1], row[5], row[7], row[8], row[9]
        if stopped is not None:
            return stopped
        if seen + lease < now or self._process_gone(host, pid):
            return seen
        return None

    def _plotter(self, db: Any, name: str, device: str | None = None, what: str = "") -> tuple[str, str | None]:
        """(port, profile) of the registered plotter ``name``; FoldfabError if there is none, or if
        ``device`` is given and the plotter is of another profile (``what``: the job, for the message)."""
        row = db.execute("SELECT port, device FROM plotters WHERE name = ?", (plotter_name(name),)).fetchone()
        if row is None:
            raise FoldfabError(f"no plotter {name!r} in queue {self.location}: foldfab queue plotters lists them "
                               "(a worker registers its plotter when it starts: foldfab queue run --port PORT "
                               "--name NAME)")
        if device is not None and row[1] is not None and row[1] != device:
            raise FoldfabError(f"plotter {name} is a {row[1]}, but {what or 'the job'} is for {device}: choose a "
                               f"plotter of {device} (foldfab queue plotters lists them), or add the job again "
                               f"for {row[1]}")
        return row[0], row[1]

    def register_plotter(self, name: str, port: str, device: str | None, worker: WorkerId, lease: float) -> None:
        """Register (or register again) the plotter ``name`` at ``port`` for ``worker``; FoldfabError if
        another worker that is still online holds the name."""
        name = plotter_name(name)
        if not port.strip():
            raise FoldfabError(f"plotter {name}: empty port: give its serial port or pyserial URL with --port")
        with self._write(create=True) as db:
            now = time.time()
            values = (worker.host, port, device, str(worker), worker.pid, now, now, lease)
            found = db.execute(f"SELECT {_COLUMNS} FROM plotters WHERE name = ?", (name,)).fetchone()
            row = found and _checked(found)
            if found and row is None:  # damaged: this registration mends it
                db.execute("DELETE FROM plotters WHERE name = ?", (name,))
            if row is None:
                taken = db.execute(f"INSERT INTO plotters ({_COLUMNS}) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, NULL) "
                                   "ON CONFLICT (name) DO NOTHING", (name, *values)).rowcount == 1
            else:
                if row[4] != str(worker) and self._offline_since(row, now) is None:
                    raise FoldfabError(
                        f"plotter {name} is registered by worker {row[4]} on {row[1]}, which runs (last heartbeat "
                        f"{now - row[7]:.0f} s ago): give this plotter another name with --name, or stop that "
                        f"worker first (its plotter is offline {max(row[7] + row[8] - now, 0):.0f} s after "
                        "its last heartbeat)")
                taken = db.execute("UPDATE plotters SET host = ?, port = ?, device = ?, worker = ?, worker_pid = ?, "
                                   "started = ?, seen = ?, lease = ?, stopped = NULL WHERE name = ? AND worker = ?",
                                   (*values, name, row[4])).rowcount == 1
            if not taken:
                raise FoldfabError(f"plotter {name} was registered by another worker at the same moment: give "
                                   "this one another name with --name")

    def plotter_alive(self, name: str, worker: WorkerId) -> bool:
        """The heartbeat of an idle worker's plotter; False if the plotter is no longer this worker's."""
        with self._write() as db:
            return db.execute("UPDATE plotters SET seen = ? WHERE name = ? AND worker = ? AND stopped IS NULL",
                              (time.time(), name, str(worker))).rowcount == 1

    @staticmethod
    def _seen(db: Any, worker: WorkerId) -> None:
        """A job's heartbeat keeps its worker's plotter online too."""
        db.execute("UPDATE plotters SET seen = ? WHERE worker = ?", (time.time(), str(worker)))

    def unregister_plotter(self, name: str, worker: WorkerId) -> None:
        """The worker stops cleanly: its plotter is offline from now on (until a worker registers it again)."""
        with self._write() as db:
            db.execute("UPDATE plotters SET stopped = ? WHERE name = ? AND worker = ?",
                       (time.time(), name, str(worker)))

    def plotters(self) -> list[PlotterRecord]:
        """Every registered plotter, by name, with what it does now."""
        if not self._exists():
            return []
        with self._read() as db:
            rows = db.execute(f"SELECT {_COLUMNS} FROM plotters ORDER BY name").fetchall()
            held = self._held_jobs(db) if rows else {}
        now = time.time()
        listed = []
        for found in rows:
            row = _checked(found)
            if row is None:
                raise FoldfabError(f"queue {self.location}: the registration of plotter {found[0]!r} is damaged "
                                   f"({found!r:.200}); its worker mends it when it starts again (foldfab queue run "
                                   "--port PORT --name NAME)")
            offline = self._offline_since(row, now)
            job = held.get(row[4]) if offline is None else None
            listed.append(PlotterRecord(*row[:5], *row[6:], offline, job))
        return listed


def _checked(row: tuple) -> tuple | None:
    """A plotter's row (:data:`_COLUMNS`) with its numbers as numbers, or None if it is damaged (rows
    are read back from a file or a server that others can write)."""
    name, host, port, device, worker, pid, *times = row
    texts = all(isinstance(text, str) for text in (name, host, port, worker)) and isinstance(device, (str, type(None)))
    numbers = all(isinstance(t, (int, float)) and math.isfinite(t) for t in times if t is not None)
    if not (texts and isinstance(pid, int) and numbers and None not in times[:3]):
        return None
    return (name, host, port, device, worker, pid, *(None if t is None else float(t) for t in times))
