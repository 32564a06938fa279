"""The queue's rules in SQL, shared by its stores: :class:`SqlQueueStore`.

The states, transitions, claim order and leases of :mod:`foldfab.queue.records`, written once
against a DB-API connection; :class:`~foldfab.queue.sqlite.SqliteQueueStore` and
:class:`~foldfab.queue.postgres.PostgresQueueStore` add the connection, transactions, locks and
error messages of their database.  SQL here is portable: ``?`` and ``:name`` parameters (the
PostgreSQL store translates them), integers for flags, ``RETURNING`` for new ids.
Standard library only (``foldfab queue list`` imports it).
"""

from __future__ import annotations

import os
import socket
import threading
import time
from contextlib import AbstractContextManager
from typing import Any, Sequence

from foldfab.errors import FoldfabError
from foldfab.queue.limits import ACTIVE, FINISHED, MAX_COPIES, MAX_JOB_ID, PRIORITIES, RUNNABLE
from foldfab.queue.records import Claim, Control, Event, JobPage, JobRecord, NewJob, WorkerId
from foldfab.queue.plotters import PlotterRegistry
from foldfab.queue.schema import resume
from foldfab.queue.snapshot import Snapshot, drawn_length, program_from, program_meta


_JOB_COLUMNS = """j.id, s.name, s.job_path, s.device, j.port, j.priority, j.copy, j.copies,
    {state}, j.created, j.updated, j.worker, j.lease_expires, j.acked_bytes, s.program_bytes,
    j.progress, j.pauses_done, j.cancel_requested, j.attempts, {reason}, j.drawn_mm, j.drawn_total_mm,
    j.plotter, j.any_plotter"""
_RESUME = resume("{t}")  # a resume (schema.resume), of the table alias t


class Queries:
    """The statements whose text depends on the dialect: ``pid_dead`` is an SQL condition that
    ``j.worker_pid`` (a process on this host) is gone; ``not_excluded`` one that ``j.id`` is not
    in the ``:exclude`` parameter; ``claim_hint`` follows ``jobs j`` in a claim's FROM (SQLite's
    ``INDEXED BY``: without statistics its planner would sort every runnable job instead)."""

    def __init__(self, pid_dead: str, not_excluded: str, claim_hint: str = ""):
        # A running or waiting job whose worker is dead (lease expired, or its process on this
        # machine gone) is reported as what the next write to the queue makes it.
        self.dead = (f"(j.lease_expires < :now OR (j.worker_host = :host AND j.worker_pid IS NOT NULL "
                     f"AND {pid_dead}))")
        self.effective_state = (f"CASE WHEN j.state IN ('running', 'waiting') AND {self.dead} THEN CASE WHEN "
                                "j.cancel_requested <> 0 THEN 'cancelled' ELSE 'interrupted' END ELSE j.state END")
        reason = (f"CASE WHEN j.state IN ('running', 'waiting') AND {self.dead} THEN "
                  "'worker ' || j.worker || ' is gone or stopped renewing its lease' ELSE j.reason END")
        self.select_jobs = (f"SELECT {_JOB_COLUMNS.format(state=self.effective_state, reason=reason)} "
                            "FROM jobs j JOIN snapshots s ON s.id = j.snapshot_id")
        # The next job for a worker: resumes first (a half-drawn sheet is on that plotter), then
        # priority, then arrival; never a plotter that is busy or holds a resume (another job's).
        # A worker with a port (its plotter :plotter) takes the jobs at that port, for its plotter by
        # name, or for any plotter of its profile, and runs them there; one without, the jobs that
        # name a port.  Nobody takes a job for another plotter.
        self.runnable_where = f"""
            WHERE j.state IN ('queued', 'interrupted')
              AND (:device IS NULL OR s.device = :device) AND (j.plotter IS NULL OR j.plotter = :plotter)
              AND CASE WHEN :port IS NULL THEN j.port <> '' ELSE j.port = :port OR j.plotter = :plotter
                                                                 OR (j.any_plotter <> 0 AND s.device = :device) END
              AND {not_excluded}
              AND NOT EXISTS (SELECT 1 FROM jobs o WHERE o.port = COALESCE(:port, j.port) AND o.id <> j.id
                              AND (o.state IN ('running', 'waiting')
                                   OR ({_RESUME.format(t='o')} AND NOT {_RESUME.format(t='j')})))"""
        self.claim_order = f"ORDER BY {_RESUME.format(t='j')} DESC, j.priority DESC, j.id"
        self.runnable = (f"{self.select_jobs} {self.runnable_where} {self.claim_order}"
                         .replace("FROM jobs j ", f"FROM jobs j {claim_hint} ", 1))


class SqlQueueStore(PlotterRegistry):
    """Every :class:`~foldfab.queue.store.QueueStore` operation, on the transactions a subclass gives:
    ``_read()`` (one consistent read) and ``_write(create)`` (one transaction that expires dead
    workers' leases first), each yielding a connection with ``execute`` and ``executemany``."""

    location: str
    queries: Queries
    for_update = ""
    """Appended to a write's read of the rows it changes (PostgreSQL locks them)."""
    skip_locked = ""
    """Appended to the expiry's read (PostgreSQL passes over rows another writer holds)."""
    survives_outages = False
    """Whether :class:`~foldfab.queue.store.QueueBusy` means the store is out of reach for a while (a
    server): a worker then plots on and saves its progress once it is back (PostgreSQL), instead of
    giving the job up before its lease ends (an SQLite file another writer holds)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._host = socket.gethostname()

    # -- what a store provides

    def _read(self) -> AbstractContextManager[Any]:
        raise NotImplementedError

    def _write(self, create: bool = False) -> AbstractContextManager[Any]:
        raise NotImplementedError

    def _exists(self) -> bool:
        """Whether the queue exists (reads of one that does not are empty)."""
        return True

    def _exclude(self, ids: Sequence[int]) -> Any:
        """The ``:exclude`` parameter's value."""
        raise NotImplementedError

    def _dead_pids(self, db: Any) -> Any:
        """The ``:dead`` parameter's value (if the dialect's ``pid_dead`` uses it)."""
        return None

    def _next_runnable(self, db: Any, params: dict) -> tuple | None:
        """The row of the job a claim takes now, locked for this transaction."""
        return db.execute(f"{self.queries.runnable} LIMIT 1", params).fetchone()

    def _lock_port(self, db: Any, port: str) -> None:
        """Keep other transactions from changing which job holds ``port`` until this one ends."""

    def _notify(self, db: Any) -> None:
        """Tell waiting workers that a job may have become runnable (when this transaction commits)."""

    def wait_for_work(self, timeout: float, stop: threading.Event) -> None:
        """Wait up to ``timeout`` s, or less when a job may have become runnable or ``stop`` is set."""
        stop.wait(timeout)

    def _params(self, db: Any, **values) -> dict:
        return {"now": time.time(), "host": self._host, "device": None, "port": None, "exclude": self._exclude(()),
                "dead": self._dead_pids(db), "plotter": None} | values

    def _held_jobs(self, db: Any) -> dict[str, JobRecord]:
        rows = db.execute(f"{self.queries.select_jobs} WHERE j.state IN ('running', 'waiting')",
                          self._params(db)).fetchall()
        return {job.worker: job for job in map(_record, rows) if job.state in ACTIVE and job.worker}

    def _process_gone(self, host: str, pid: int) -> bool:
        return host == self._host and not pid_alive(pid)

    def _no_job(self, job_id: int) -> FoldfabError:
        return FoldfabError(f"no job {job_id} in queue {self.location}; see foldfab queue list")

    # -- helpers inside a transaction

    def _expire(self, db: Any) -> None:
        params = self._params(db)
        rows = db.execute("SELECT j.id, j.worker, j.lease_expires, j.cancel_requested FROM jobs j "
                          f"WHERE j.state IN ('running', 'waiting') AND {self.queries.dead} {self.skip_locked}",
                          params).fetchall()
        for job_id, worker, expires, cancel in rows:
            if expires < params["now"]:
                why = (f"lease expired: worker {worker} stopped renewing it at "
                       f"{time.strftime('%H:%M:%S', time.localtime(expires))} (killed, crashed, hung, or its "
                       "machine went off)")
            else:
                why = f"worker {worker} is gone (its process on this machine no longer exists)"
            state = "cancelled" if cancel else "interrupted"
            self._set(db, job_id, state=state, worker=None, lease_expires=None, worker_host=None,
                      worker_pid=None, cancel_requested=0, reason=why)
            self._event(db, job_id, state, why if cancel else
                        why + "; the next run resumes it from the last acknowledged stroke")
        if rows:
            self._notify(db)

    @staticmethod
    def _set(db: Any, job_id: int, **values) -> None:
        columns = ", ".join(f"{key} = ?" for key in values)
        db.execute(f"UPDATE jobs SET {columns}, updated = ? WHERE id = ?", (*values.values(), time.time(), job_id))

    @staticmethod
    def _event(db: Any, job_id: int, kind: str, message: str) -> None:
        db.execute("INSERT INTO events (job_id, time, kind, message) VALUES (?, ?, ?, ?)",
                   (job_id, time.time(), kind, message))

    def _get(self, db: Any, job_id: int, lock: bool = False) -> JobRecord:
        row = db.execute(f"{self.queries.select_jobs} WHERE j.id = :id {self.for_update if lock else ''}",
                         self._params(db, id=_job_id(job_id))).fetchone()
        if row is None:
            raise self._no_job(job_id)
        return _record(row)

    def _owned(self, db: Any, job_id: int, worker: WorkerId) -> tuple[str, bool] | None:
        """(state, cancel requested) of a job ``worker`` holds, or None if it holds it no longer."""
        row = db.execute(f"SELECT state, cancel_requested, worker FROM jobs j WHERE id = ? {self.for_update}",
                         (job_id,)).fetchone()
        return (row[0], bool(row[1])) if row and row[2] == str(worker) and row[0] in ACTIVE else None

    def _lapsed(self, db: Any, job_id: int, worker: WorkerId) -> tuple[str, bool] | None:
        """Take back a job ``worker`` held whose lease lapsed while it could not reach the queue, if
        nobody took it, retried or cancelled it meanwhile (it is still interrupted for that reason):
        the worker plotted on, so the job is running.  Only on a store that survives outages: on
        the others a worker that let its lease lapse has stopped its plotter (it lost the job)."""
        if not self.survives_outages:
            return None
        row = db.execute(f"SELECT state, reason FROM jobs j WHERE id = ? {self.for_update}", (job_id,)).fetchone()
        if not (row and row[0] == "interrupted" and (row[1] or "").startswith(f"lease expired: worker {worker} ")):
            return None
        self._set(db, job_id, state="running", worker=str(worker), worker_host=worker.host, worker_pid=worker.pid,
                  reason=None)
        self._event(db, job_id, "reconnected", f"worker {worker} is back after its lease lapsed (nobody took the "
                                               "job meanwhile): it plotted on, and goes on")
        return ("running", False)

    # -- operator side

    def add(self, jobs: Sequence[NewJob]) -> list[int]:
        for new in jobs:
            if not (new.port.strip() or new.plotter is not None or new.any_plotter):
                raise FoldfabError(f"{new.snapshot.name}: empty port: give a serial port or pyserial URL")
            if not (PRIORITIES[0] <= new.priority <= PRIORITIES[1] and 1 <= new.copies <= MAX_COPIES):
                raise ValueError(f"priority must be from {PRIORITIES[0]} to {PRIORITIES[1]} and copies from 1 "
                                 f"to {MAX_COPIES}, got {new.priority} and {new.copies}")
        ids = []
        lengths = [drawn_length(new.snapshot) for new in jobs]  # before the write lock: no writer waits on it
        with self._write(create=True) as db:
            now = time.time()
            for new, length in zip(jobs, lengths):
                snap = new.snapshot
                port = new.port if new.plotter is None else self._plotter(db, new.plotter, snap.device, snap.name)[0]
                where = (f"on plotter {new.plotter} ({port})" if new.plotter is not None else
                         f"on any plotter of {snap.device}" if new.any_plotter else f"on {snap.device} at {port}")
                snapshot_id = db.execute(
                    "INSERT INTO snapshots (name, job_path, device, program_bytes, program_sha256, program_meta, "
                    "job_text, device_text, program) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?) RETURNING id",
                    (snap.name, snap.job_path, snap.device, len(snap.program.text), snap.sha256,
                     program_meta(snap.program), snap.job_text, snap.device_text, snap.program.text)).fetchone()[0]
                for copy in range(1, new.copies + 1):
                    job_id = db.execute(
                        "INSERT INTO jobs (snapshot_id, port, priority, copy, copies, created, updated, "
                        "drawn_total_mm, plotter, any_plotter) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?) RETURNING id",
                        (snapshot_id, port, new.priority, copy, new.copies, now, now, length, new.plotter,
                         int(new.any_plotter and new.plotter is None))).fetchone()[0]
                    label = f" (copy {copy} of {new.copies})" if new.copies > 1 else ""
                    self._event(db, job_id, "queued",
                                f"queued{label}: {snap.job_path} {where}, priority "
                                f"{new.priority}, program {len(snap.program.text)} bytes, sha256 {snap.sha256[:16]}")
                    ids.append(job_id)
            self._notify(db)
        return ids

    def jobs(self, state: str | None = None) -> list[JobRecord]:
        return self.page(state).jobs

    def page(self, state: str | None = None, after: int = 0, limit: int | None = None) -> JobPage:
        if limit is not None and limit < 1:
            raise ValueError("a page holds one job or more")
        if not self._exists():
            return JobPage([], 0)
        with self._read() as db:
            where = "WHERE j.id > :after" + (f" AND {self.queries.effective_state} = :state" if state else "")
            params = self._params(db, state=state, after=min(max(after, 0), MAX_JOB_ID), limit=limit)
            # the primary key serves ORDER BY j.id with LIMIT: a page reads its own rows, not the queue
            rows = db.execute(f"{self.queries.select_jobs} {where} ORDER BY j.id"
                              + (" LIMIT :limit" if limit is not None else ""), params).fetchall()
            more = 0
            if limit is not None and len(rows) == limit:
                more = db.execute(f"SELECT count(*) FROM jobs j {where}", params | {"after": rows[-1][0]}).fetchone()[0]
        return JobPage([_record(row) for row in rows], more)

    def job(self, job_id: int) -> JobRecord:
        with self._read() as db:
            return self._get(db, job_id)

    def events(self, job_id: int) -> list[Event]:
        with self._read() as db:
            rows = db.execute("SELECT time, kind, message FROM events WHERE job_id = ? ORDER BY id",
                              (_job_id(job_id),)).fetchall()
        return [Event(*row) for row in rows]

    def snapshot(self, job_id: int) -> Snapshot:
        with self._read() as db:
            row = self._snapshot_row(db, job_id)
        return self._checked_snapshot(job_id, row)

    @staticmethod
    def _snapshot_row(db: Any, job_id: int) -> tuple | None:
        return db.execute("SELECT s.name, s.job_path, s.job_text, s.device, s.device_text, s.program, "
                          "s.program_meta, s.program_sha256 FROM jobs j JOIN snapshots s "
                          "ON s.id = j.snapshot_id WHERE j.id = ?", (_job_id(job_id),)).fetchone()

    def _checked_snapshot(self, job_id: int, row: tuple | None) -> Snapshot:
        """The snapshot in ``row``; FoldfabError if there is none or its program does not match its hash."""
        if row is None:
            raise self._no_job(job_id)
        *texts, program, meta, digest = row
        snap = Snapshot(*texts, program_from(program, meta))
        if snap.sha256 != digest:
            raise FoldfabError(f"job {job_id}: its stored program does not match its SHA-256 (the queue "
                               f"{self.location} was damaged or edited); remove the job and add it again")
        return snap

    def cancel(self, job_id: int) -> JobRecord:
        with self._write() as db:
            job = self._get(db, job_id, lock=True)
            if job.state in RUNNABLE:
                self._set(db, job_id, state="cancelled", reason="cancelled by the operator")
                self._event(db, job_id, "cancelled", f"cancelled by the operator (was {job.state})")
                self._notify(db)  # a cancelled resume frees its plotter
            elif job.state in ACTIVE and not job.cancel_requested:
                self._set(db, job_id, cancel_requested=1)
                self._event(db, job_id, "cancel", f"cancel requested: worker {job.worker} stops the plotter "
                                                  "(pen up, parked) and ends the job")
            elif job.state not in ACTIVE:
                raise FoldfabError(f"job {job_id} is {job.state}, nothing to cancel"
                                   + ("; remove it with foldfab queue remove" if job.state in FINISHED else ""))
            return self._get(db, job_id)

    def retry(self, job_id: int, restart: bool = False, port: str | None = None,
              plotter: str | None = None) -> JobRecord:
        with self._write() as db:
            job = self._get(db, job_id, lock=True)
            if job.state not in ("failed", "cancelled", "interrupted"):
                raise FoldfabError(f"job {job_id} is {job.state}; only failed, cancelled or interrupted jobs "
                                   "can be retried")
            if port is not None and not port.strip():
                raise FoldfabError(f"job {job_id}: empty port: give a serial port or pyserial URL with --port")
            if plotter is not None:
                port = self._plotter(db, plotter, job.device, f"job {job_id}")[0]
            self._lock_port(db, port or job.port)
            where = "from the start, on a new sheet" if restart or not job.acked_bytes else \
                f"from byte {job.acked_bytes} of {job.program_bytes} (the last acknowledged stroke)"
            values = {"acked_bytes": 0, "pauses_done": 0, "progress": "", "drawn_mm": 0} if restart else {}
            if port is not None:  # the operator moved the sheet: to that plotter (or port) only
                values.update(port=port, plotter=plotter, any_plotter=0)
                where += f", {f'on plotter {plotter} ' if plotter else ''}at {port} (was {job.target} at {job.port})"
            self._set(db, job_id, state="queued", reason=None, **values)
            self._event(db, job_id, "retried", f"queued again (was {job.state}): runs {where}")
            self._notify(db)
            return self._get(db, job_id)

    def continue_job(self, job_id: int, source: str) -> JobRecord:
        with self._write() as db:
            job = self._get(db, job_id, lock=True)
            if job.state != "waiting":
                raise FoldfabError(f"job {job_id} is {job.state}, not waiting at a pause; nothing to continue")
            self._set(db, job_id, state="running")
            self._event(db, job_id, "continued", f"the operator continued ({source})")
            return self._get(db, job_id)

    def remove(self, job_id: int) -> None:
        with self._write() as db:
            job = self._get(db, job_id, lock=True)
            if job.state in ACTIVE:
                raise FoldfabError(f"job {job_id} is {job.state} on worker {job.worker}; cancel it first "
                                   f"(foldfab queue cancel {job_id})")
            self._delete(db, "id = ?", (job_id,))
            self._notify(db)

    def clear(self, states: Sequence[str]) -> int:
        if not set(states) <= set(FINISHED):
            raise ValueError(f"only finished jobs ({', '.join(FINISHED)}) can be cleared")
        if not self._exists():
            return 0
        with self._write() as db:
            return self._delete(db, f"state IN ({', '.join('?' * len(states))})", tuple(states))

    @staticmethod
    def _delete(db: Any, where: str, params: tuple) -> int:
        """Delete jobs (their events cascade) and the snapshots no job uses any more."""
        rows = db.execute(f"SELECT id, snapshot_id FROM jobs WHERE {where}", params).fetchall()
        db.executemany("DELETE FROM jobs WHERE id = ?", [(job_id,) for job_id, _ in rows])
        db.executemany("DELETE FROM snapshots WHERE id = ? AND NOT EXISTS "
                       "(SELECT 1 FROM jobs WHERE snapshot_id = ?)", [(s, s) for s in {s for _, s in rows}])
        return len(rows)

    # -- worker side

    def runnable(self, device: str | None = None, port: str | None = None,
                 exclude: Sequence[int] = (), plotter: str | None = None) -> list[JobRecord]:
        if not self._exists():
            return []
        with self._read() as db:
            rows = db.execute(self.queries.runnable, self._params(db, device=device, port=port, plotter=plotter,
                                                                  exclude=self._exclude(exclude))).fetchall()
        return [_record(row) for row in rows]

    def claim(self, worker: WorkerId, lease: float, device: str | None = None, port: str | None = None,
              exclude: Sequence[int] = (), plotter: str | None = None) -> Claim | None:
        if not self._exists():
            return None
        with self._write() as db:
            params = self._params(db, device=device, port=port, exclude=self._exclude(exclude), plotter=plotter)
            row = self._next_runnable(db, params)
            if row is None:
                return None
            job = _record(row)
            self._set(db, job.id, state="running", worker=str(worker), worker_host=worker.host,
                      worker_pid=worker.pid, lease_expires=time.time() + lease, attempts=job.attempts + 1,
                      cancel_requested=0, reason=None, port=port or job.port, plotter=plotter or job.plotter,
                      any_plotter=0)  # from now on its sheet is on this plotter
            what = f"resumed at byte {job.acked_bytes} of {job.program_bytes}" if job.acked_bytes else "started"
            on = f" on plotter {plotter} at {port}" if plotter else f" at {port}" if port and job.any_plotter else ""
            self._event(db, job.id, "started", f"{what} by worker {worker}{on} (attempt {job.attempts + 1})")
            job = self._get(db, job.id)
            # the snapshot in the claim's own transaction: a server lost once it commits must not
            # pass for a damaged snapshot (the worker would fail the job) nor leave the job held
            row = self._snapshot_row(db, job.id)
        try:
            return Claim(job, self._checked_snapshot(job.id, row))
        except FoldfabError as exc:  # damaged: the worker fails the job (and says so), not itself
            return Claim(job, None, str(exc))

    def heartbeat(self, job_id: int, worker: WorkerId, lease: float, acked_bytes: int | None = None,
                  progress: str | None = None, pauses_done: int | None = None,
                  drawn: tuple[float, float] | None = None) -> Control:
        with self._write() as db:
            owned = self._owned(db, job_id, worker) or self._lapsed(db, job_id, worker)
            if owned is None:
                return Control("lost", False, True)
            values = _given(acked_bytes=acked_bytes, progress=progress, pauses_done=pauses_done, drawn=drawn)
            self._set(db, job_id, lease_expires=time.time() + lease, **values)
            self._seen(db, worker)
            return Control(*owned, False)

    def log(self, job_id: int, kind: str, message: str) -> None:
        with self._write() as db:
            self._event(db, job_id, kind, message)

    def wait_at_pause(self, job_id: int, worker: WorkerId, message: str) -> Control:
        with self._write() as db:
            owned = self._owned(db, job_id, worker)
            if owned is None:
                return Control("lost", False, True)
            self._set(db, job_id, state="waiting")
            self._event(db, job_id, "pause", message)
            return Control("waiting", owned[1], False)

    def finish(self, job_id: int, worker: WorkerId, state: str, message: str,
               acked_bytes: int | None = None, pauses_done: int | None = None,
               progress: str | None = None, drawn: tuple[float, float] | None = None) -> bool:
        if state not in ("done", "failed", "cancelled", "interrupted"):
            raise ValueError(f"a job cannot finish as {state!r}")
        with self._write() as db:
            if self._owned(db, job_id, worker) is None and self._lapsed(db, job_id, worker) is None:
                return False
            values = _given(acked_bytes=acked_bytes, pauses_done=pauses_done, progress=progress, drawn=drawn)
            self._set(db, job_id, state=state, worker=None, lease_expires=None, worker_host=None,
                      worker_pid=None, cancel_requested=0, reason=None if state == "done" else message,
                      **values)
            self._event(db, job_id, state, message)
            self._notify(db)  # the plotter is free
            return True


def pid_alive(pid: int) -> bool:
    """Whether process ``pid`` runs on this machine (a zombie, killed but not yet reaped, does not)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # it exists, under another user
        pass
    try:
        with open(f"/proc/{pid}/stat", "rb") as stat:
            return stat.read().rsplit(b")", 1)[1].split()[0] != b"Z"
    except (OSError, IndexError):  # no /proc (not Linux): trust kill
        return True


def _job_id(job_id: int) -> int:
    """``job_id`` as the databases take it: ids beyond their integers (no such job) as -1."""
    return job_id if -MAX_JOB_ID <= job_id <= MAX_JOB_ID else -1


def _given(drawn: tuple[float, float] | None = None, **values) -> dict:
    """The values that are not None, as columns (``drawn``: drawn_mm and drawn_total_mm)."""
    if drawn is not None:
        values.update(drawn_mm=drawn[0], drawn_total_mm=drawn[1])
    return {key: value for key, value in values.items() if value is not None}


def _record(row: tuple) -> JobRecord:
    values = list(row)
    values[17] = bool(values[17])  # cancel_requested
    values[23] = bool(values[23])  # any_plotter
    return JobRecord(*values)
