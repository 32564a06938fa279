"""The queue in one SQLite file: schema, migrations and :class:`SqliteQueueStore`.

Every change is one ``BEGIN IMMEDIATE`` transaction; the file is in WAL mode (local disks
only: WAL needs shared memory, so not NFS).  Leases compare wall clocks, so hosts that
share a queue need synchronized clocks (NTP).
This module is imported by ``foldfab queue list``: standard library only.
"""

from __future__ import annotations

import json
import os
import socket
import sqlite3
import threading
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator, Sequence

from foldfab.errors import FoldfabError
from foldfab.queue.records import (ACTIVE, FINISHED, MAX_COPIES, MAX_JOB_ID, PRIORITIES, RUNNABLE, Claim, Control,
                                   Event, JobRecord, NewJob, WorkerId)
from foldfab.queue.snapshot import Snapshot, drawn_length, program_from, program_meta
from foldfab.queue.store import DEFAULT_WAIT, QueueBusy
from foldfab.xdg import foldfab_dir

def default_queue_path() -> Path:
    """``$FOLDFAB_QUEUE``, else ``$XDG_DATA_HOME/foldfab/queue.sqlite3`` (default ``~/.local/share``)."""
    if os.environ.get("FOLDFAB_QUEUE"):
        return Path(os.environ["FOLDFAB_QUEUE"])
    return foldfab_dir("XDG_DATA_HOME") / "queue.sqlite3"


MIGRATIONS: tuple[str, ...] = (
    # version 1: snapshots (program text last, so listing never reads it), jobs, events
    """
    CREATE TABLE snapshots (
        id INTEGER PRIMARY KEY AUTOINCREMENT,
        name TEXT NOT NULL,
        job_path TEXT NOT NULL,
        device TEXT NOT NULL,
        program_bytes INTEGER NOT NULL,
        program_sha256 TEXT NOT NULL,
        program_meta TEXT NOT NULL,
        job_text TEXT NOT NULL,
        device_text TEXT NOT NULL,
        program TEXT NOT NULL
    );
    CREATE TABLE jobs (
        id INTEGER PRIMARY KEY AUTOINCREMENT,
        snapshot_id INTEGER NOT NULL REFERENCES snapshots(id),
        port TEXT NOT NULL,
        priority INTEGER NOT NULL DEFAULT 0,
        copy INTEGER NOT NULL DEFAULT 1,
        copies INTEGER NOT NULL DEFAULT 1,
        state TEXT NOT NULL DEFAULT 'queued' CHECK (state IN
            ('queued', 'running', 'waiting', 'done', 'failed', 'cancelled', 'interrupted')),
        created REAL NOT NULL,
        updated REAL NOT NULL,
        worker TEXT,
        lease_expires REAL,
        acked_bytes INTEGER NOT NULL DEFAULT 0,
        pauses_done INTEGER NOT NULL DEFAULT 0,
        cancel_requested INTEGER NOT NULL DEFAULT 0,
        attempts INTEGER NOT NULL DEFAULT 0,
        reason TEXT
    );
    CREATE TABLE events (
        id INTEGER PRIMARY KEY AUTOINCREMENT,
        job_id INTEGER NOT NULL REFERENCES jobs(id) ON DELETE CASCADE,
        time REAL NOT NULL,
        kind TEXT NOT NULL,
        message TEXT NOT NULL
    );
    CREATE INDEX events_by_job ON events(job_id, id);
    """,
    # version 2: progress text for list/show; worker host and pid, so a worker that died on
    # this machine is noticed at once instead of when its lease expires; claim indexes
    """
    ALTER TABLE jobs ADD COLUMN progress TEXT NOT NULL DEFAULT '';
    ALTER TABLE jobs ADD COLUMN worker_host TEXT;
    ALTER TABLE jobs ADD COLUMN worker_pid INTEGER;
    CREATE INDEX jobs_by_state ON jobs(state, priority DESC, id);
    CREATE INDEX jobs_by_port ON jobs(port, state);
    CREATE INDEX jobs_by_snapshot ON jobs(snapshot_id);
    """,
    # version 3: the length drawn and in all, so that list shows the share done as plot does
    """
    ALTER TABLE jobs ADD COLUMN drawn_mm REAL NOT NULL DEFAULT 0;
    ALTER TABLE jobs ADD COLUMN drawn_total_mm REAL NOT NULL DEFAULT 0;
    """,
)
SCHEMA_VERSION = len(MIGRATIONS)

_JOB_COLUMNS = """j.id, s.name, s.job_path, s.device, j.port, j.priority, j.copy, j.copies,
    {state}, j.created, j.updated, j.worker, j.lease_expires, j.acked_bytes, s.program_bytes,
    j.progress, j.pauses_done, j.cancel_requested, j.attempts, {reason}, j.drawn_mm, j.drawn_total_mm"""
# A running or waiting job whose worker is dead (lease expired, or its process on this machine
# gone) is reported as what the next write to the queue makes it.
_DEAD = ("(j.lease_expires < :now OR (j.worker_host = :host AND j.worker_pid IS NOT NULL "
         "AND NOT foldfab_pid_alive(j.worker_pid)))")
_EFFECTIVE_STATE = (f"CASE WHEN j.state IN ('running', 'waiting') AND {_DEAD} THEN "
                    "CASE WHEN j.cancel_requested THEN 'cancelled' ELSE 'interrupted' END ELSE j.state END")
_EFFECTIVE_REASON = (f"CASE WHEN j.state IN ('running', 'waiting') AND {_DEAD} THEN "
                     "'worker ' || j.worker || ' is gone or stopped renewing its lease' ELSE j.reason END")
_SELECT_JOBS = (f"SELECT {_JOB_COLUMNS.format(state=_EFFECTIVE_STATE, reason=_EFFECTIVE_REASON)} "
                "FROM jobs j JOIN snapshots s ON s.id = j.snapshot_id")
# A resume: a job whose sheet is half drawn on its plotter, interrupted, or queued again by
# retry without --restart after part of it was acknowledged.
_RESUME = "({t}.state = 'interrupted' OR ({t}.state = 'queued' AND {t}.acked_bytes > 0))"
# The next job for a worker: resumes first (a half-drawn sheet is on that plotter), then
# priority, then arrival; never a plotter that is busy or holds a resume (another job's).
_CLAIM_ORDER = f"ORDER BY {_RESUME.format(t='j')} DESC, j.priority DESC, j.id"
_RUNNABLE = f"""{_SELECT_JOBS}
    WHERE j.state IN ('queued', 'interrupted')
      AND (:device IS NULL OR s.device = :device) AND (:port IS NULL OR j.port = :port)
      AND j.id NOT IN (SELECT value FROM json_each(:exclude))
      AND NOT EXISTS (SELECT 1 FROM jobs o WHERE o.port = j.port AND o.id <> j.id
                      AND (o.state IN ('running', 'waiting')
                           OR ({_RESUME.format(t='o')} AND NOT {_RESUME.format(t='j')})))
    {_CLAIM_ORDER}"""


def _pid_alive(pid: int) -> bool:
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


class SqliteQueueStore:
    """The queue in one SQLite file in WAL mode, shared by threads, processes and hosts' workers
    (on a local disk).  ``wait``: seconds to wait for another writer before giving up."""

    def __init__(self, path: str | os.PathLike, wait: float = DEFAULT_WAIT):
        self.path = Path(path)
        self.location = str(self.path)
        self.wait = wait
        self._lock = threading.Lock()
        self._host = socket.gethostname()
        self._db: sqlite3.Connection | None = None

    # -- connection, errors, migrations

    def _connect(self) -> sqlite3.Connection:
        if self._db is None:
            if self.path.is_dir():
                raise FoldfabError(self._folder_message())
            try:
                self.path.parent.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise FoldfabError(f"queue file {self.path}: cannot create its folder ({exc.strerror}); "
                                   "choose another with --queue or FOLDFAB_QUEUE") from None
            db = sqlite3.connect(self.path, timeout=self.wait, isolation_level=None, check_same_thread=False)
            try:
                db.create_function("foldfab_pid_alive", 1, _pid_alive)
                db.execute(f"PRAGMA busy_timeout = {int(self.wait * 1000)}")
                db.execute("PRAGMA foreign_keys = ON")
                self._migrate(db)
            except BaseException:
                db.close()
                raise
            self._db = db
        return self._db

    def _migrate(self, db: sqlite3.Connection) -> None:
        version = db.execute("PRAGMA user_version").fetchone()[0]
        if version > SCHEMA_VERSION:
            raise FoldfabError(f"queue file {self.path} has schema version {version}, but this foldfab knows "
                               f"only up to {SCHEMA_VERSION}: upgrade foldfab, or choose another queue with --queue")
        if version == SCHEMA_VERSION:
            return
        if version == 0 and db.execute("SELECT count(*) FROM sqlite_master").fetchone()[0]:
            raise FoldfabError(f"{self.path} is an SQLite file but not a foldfab queue; "
                               "choose another file with --queue or FOLDFAB_QUEUE")
        db.execute("PRAGMA journal_mode = WAL")
        db.execute("BEGIN IMMEDIATE")
        try:
            version = db.execute("PRAGMA user_version").fetchone()[0]  # another process may have migrated
            for step in range(version, SCHEMA_VERSION):
                for statement in MIGRATIONS[step].split(";"):
                    if statement.strip():
                        db.execute(statement)
            db.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")
            db.execute("COMMIT")
        except BaseException:
            _rollback(db)
            raise

    @contextmanager
    def _errors(self) -> Iterator[None]:
        """Turn SQLite's errors into one line that names the file and what to do."""
        try:
            yield
        except sqlite3.DatabaseError as exc:
            name = getattr(exc, "sqlite_errorname", "")
            where = f"queue file {self.path}"
            if name.startswith("SQLITE_BUSY") or name.startswith("SQLITE_LOCKED"):
                raise QueueBusy(f"{where} is busy: another foldfab kept it locked for more than {self.wait:g} s; "
                                "nothing was changed; try again (or wait longer with --wait)") from None
            if name.startswith("SQLITE_FULL"):
                message = (f"{where}: the disk is full (SQLite: {exc}); nothing was changed; free space on the "
                           f"disk that holds {self.path.parent}, or choose a queue on another disk with --queue")
            elif name == "SQLITE_READONLY_DIRECTORY":
                message = (f"{where}: its folder is not writable, and SQLite needs to create "
                           f"{self.path.name}-wal and {self.path.name}-shm beside it; nothing was changed; "
                           "make the folder writable, or choose another queue with --queue")
            elif (name.startswith("SQLITE_CANTOPEN") and not self.path.exists()
                  and not os.access(self.path.parent, os.W_OK)):
                message = (f"{where} cannot be created: its folder {self.path.parent} is not writable for you; "
                           "nothing was changed; make the folder writable, or choose another queue with --queue")
            elif name.startswith("SQLITE_CANTOPEN") and self.path.exists() and not os.access(self.path, os.R_OK):
                message = (f"{where} is not readable for you ({exc}); nothing was changed; ask its owner for "
                           "read and write access, or choose another queue with --queue")
            elif name.startswith(("SQLITE_READONLY", "SQLITE_CANTOPEN", "SQLITE_PERM")):
                message = (f"{where} is read-only for you ({exc}); nothing was changed; ask its owner for "
                           "write access, or choose another queue with --queue")
            elif name.startswith(("SQLITE_NOTADB", "SQLITE_CORRUPT")):
                message = (f"{where} is damaged ({exc}); nothing was changed; move it aside "
                           f"(mv {self.path} {self.path}.damaged) to start a new queue, or recover its jobs "
                           f"with: sqlite3 {self.path} .recover")
            else:
                message = f"{where}: {exc}; nothing was changed"
            raise FoldfabError(message) from None

    def _folder_message(self) -> str:
        return (f"queue file {self.path} is a folder: give the path of a file in it (such as "
                f"{self.path / 'queue.sqlite3'}) with --queue or FOLDFAB_QUEUE")

    def _must_exist(self) -> None:
        """Only adding creates the queue file; other commands on a missing one say so."""
        if not self.path.exists():
            raise FoldfabError(f"queue {self.path} is empty: it does not exist yet (foldfab queue add creates it)")

    @contextmanager
    def _read(self) -> Iterator[sqlite3.Connection]:
        """One consistent read."""
        self._must_exist()
        with self._lock, self._errors():
            db = self._connect()
            db.execute("BEGIN")
            try:
                yield db
            finally:
                db.execute("COMMIT")

    @contextmanager
    def _write(self, create: bool = False) -> Iterator[sqlite3.Connection]:
        """One transaction that takes the write lock first, then expires dead workers' leases."""
        if not create:
            self._must_exist()
        with self._lock, self._errors():
            db = self._connect()
            db.execute("BEGIN IMMEDIATE")
            try:
                self._expire(db)
                yield db
                db.execute("COMMIT")
            except BaseException:
                _rollback(db)
                raise

    def _params(self, **values) -> dict:
        return {"now": time.time(), "host": self._host, "device": None, "port": None, "exclude": "[]"} | values

    def close(self) -> None:
        """Close the connection (the file stays)."""
        with self._lock:
            if self._db is not None:
                self._db.close()
                self._db = None

    # -- helpers inside a transaction

    def _expire(self, db: sqlite3.Connection) -> None:
        params = self._params()
        rows = db.execute("SELECT j.id, j.worker, j.lease_expires, j.cancel_requested FROM jobs j "
                          f"WHERE j.state IN ('running', 'waiting') AND {_DEAD}", params).fetchall()
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

    @staticmethod
    def _set(db: sqlite3.Connection, job_id: int, **values) -> None:
        columns = ", ".join(f"{key} = ?" for key in values)
        db.execute(f"UPDATE jobs SET {columns}, updated = ? WHERE id = ?", (*values.values(), time.time(), job_id))

    @staticmethod
    def _event(db: sqlite3.Connection, job_id: int, kind: str, message: str) -> None:
        db.execute("INSERT INTO events (job_id, time, kind, message) VALUES (?, ?, ?, ?)",
                   (job_id, time.time(), kind, message))

    def _get(self, db: sqlite3.Connection, job_id: int) -> JobRecord:
        row = db.execute(f"{_SELECT_JOBS} WHERE j.id = :id", self._params(id=_job_id(job_id))).fetchone()
        if row is None:
            raise self._no_job(job_id)
        return _record(row)

    def _no_job(self, job_id: int) -> FoldfabError:
        return FoldfabError(f"no job {job_id} in queue {self.path}; see foldfab queue list")

    @staticmethod
    def _owned(db: sqlite3.Connection, job_id: int, worker: WorkerId) -> tuple[str, bool] | None:
        """(state, cancel requested) of a job ``worker`` holds, or None if it holds it no longer."""
        row = db.execute("SELECT state, cancel_requested, worker FROM jobs WHERE id = ?", (job_id,)).fetchone()
        return (row[0], bool(row[1])) if row and row[2] == str(worker) and row[0] in ACTIVE else None

    # -- operator side

    def add(self, jobs: Sequence[NewJob]) -> list[int]:
        for new in jobs:
            if not new.port.strip():
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
                snapshot_id = db.execute(
                    "INSERT INTO snapshots (name, job_path, device, program_bytes, program_sha256, program_meta, "
                    "job_text, device_text, program) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
                    (snap.name, snap.job_path, snap.device, len(snap.program.text), snap.sha256,
                     program_meta(snap.program), snap.job_text, snap.device_text, snap.program.text)).lastrowid
                for copy in range(1, new.copies + 1):
                    job_id = db.execute(
                        "INSERT INTO jobs (snapshot_id, port, priority, copy, copies, created, updated, drawn_total_mm) "
                        "VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                        (snapshot_id, new.port, new.priority, copy, new.copies, now, now, length)).lastrowid
                    label = f" (copy {copy} of {new.copies})" if new.copies > 1 else ""
                    self._event(db, job_id, "queued",
                                f"queued{label}: {snap.job_path} on {snap.device} at {new.port}, priority "
                                f"{new.priority}, program {len(snap.program.text)} bytes, sha256 {snap.sha256[:16]}")
                    ids.append(job_id)
        return ids

    def jobs(self, state: str | None = None) -> list[JobRecord]:
        if not self.path.exists():
            return []
        with self._read() as db:
            where = f"WHERE {_EFFECTIVE_STATE} = :state" if state else ""
            rows = db.execute(f"{_SELECT_JOBS} {where} ORDER BY j.id", self._params(state=state)).fetchall()
        return [_record(row) for row in rows]

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
            row = db.execute("SELECT s.name, s.job_path, s.job_text, s.device, s.device_text, s.program, "
                             "s.program_meta, s.program_sha256 FROM jobs j JOIN snapshots s "
                             "ON s.id = j.snapshot_id WHERE j.id = ?", (_job_id(job_id),)).fetchone()
        if row is None:
            raise self._no_job(job_id)
        *texts, program, meta, digest = row
        snap = Snapshot(*texts, program_from(program, meta))
        if snap.sha256 != digest:
            raise FoldfabError(f"job {job_id}: its stored program does not match its SHA-256 (the queue file "
                               f"{self.path} was damaged or edited); remove the job and add it again")
        return snap

    def cancel(self, job_id: int) -> JobRecord:
        with self._write() as db:
            job = self._get(db, job_id)
            if job.state in RUNNABLE:
                self._set(db, job_id, state="cancelled", reason="cancelled by the operator")
                self._event(db, job_id, "cancelled", f"cancelled by the operator (was {job.state})")
            elif job.state in ACTIVE and not job.cancel_requested:
                self._set(db, job_id, cancel_requested=1)
                self._event(db, job_id, "cancel", f"cancel requested: worker {job.worker} stops the plotter "
                                                  "(pen up, parked) and ends the job")
            elif job.state not in ACTIVE:
                raise FoldfabError(f"job {job_id} is {job.state}, nothing to cancel"
                                   + ("; remove it with foldfab queue remove" if job.state in FINISHED else ""))
            return self._get(db, job_id)

    def retry(self, job_id: int, restart: bool = False, port: str | None = None) -> JobRecord:
        with self._write() as db:
            job = self._get(db, job_id)
            if job.state not in ("failed", "cancelled", "interrupted"):
                raise FoldfabError(f"job {job_id} is {job.state}; only failed, cancelled or interrupted jobs "
                                   "can be retried")
            if port is not None and not port.strip():
                raise FoldfabError(f"job {job_id}: empty port: give a serial port or pyserial URL with --port")
            where = "from the start, on a new sheet" if restart or not job.acked_bytes else \
                f"from byte {job.acked_bytes} of {job.program_bytes} (the last acknowledged stroke)"
            values = {"acked_bytes": 0, "pauses_done": 0, "progress": "", "drawn_mm": 0} if restart else {}
            if port is not None:
                values["port"] = port
                where += f", at {port} (was {job.port})"
            self._set(db, job_id, state="queued", reason=None, **values)
            self._event(db, job_id, "retried", f"queued again (was {job.state}): runs {where}")
            return self._get(db, job_id)

    def continue_job(self, job_id: int, source: str) -> JobRecord:
        with self._write() as db:
            job = self._get(db, job_id)
            if job.state != "waiting":
                raise FoldfabError(f"job {job_id} is {job.state}, not waiting at a pause; nothing to continue")
            self._set(db, job_id, state="running")
            self._event(db, job_id, "continued", f"the operator continued ({source})")
            return self._get(db, job_id)

    def remove(self, job_id: int) -> None:
        with self._write() as db:
            job = self._get(db, job_id)
            if job.state in ACTIVE:
                raise FoldfabError(f"job {job_id} is {job.state} on worker {job.worker}; cancel it first "
                                   f"(foldfab queue cancel {job_id})")
            self._delete(db, "id = ?", (job_id,))

    def clear(self, states: Sequence[str]) -> int:
        if not set(states) <= set(FINISHED):
            raise ValueError(f"only finished jobs ({', '.join(FINISHED)}) can be cleared")
        if not self.path.exists():
            return 0
        with self._write() as db:
            return self._delete(db, f"state IN ({', '.join('?' * len(states))})", tuple(states))

    @staticmethod
    def _delete(db: sqlite3.Connection, where: str, params: tuple) -> int:
        """Delete jobs (their events cascade) and the snapshots no job uses any more."""
        rows = db.execute(f"SELECT id, snapshot_id FROM jobs WHERE {where}", params).fetchall()
        db.executemany("DELETE FROM jobs WHERE id = ?", [(job_id,) for job_id, _ in rows])
        db.executemany("DELETE FROM snapshots WHERE id = ? AND NOT EXISTS "
                       "(SELECT 1 FROM jobs WHERE snapshot_id = ?)", [(s, s) for s in {s for _, s in rows}])
        return len(rows)

    # -- worker side

    def runnable(self, device: str | None = None, port: str | None = None,
                 exclude: Sequence[int] = ()) -> list[JobRecord]:
        if not self.path.exists():
            return []
        with self._read() as db:
            rows = db.execute(_RUNNABLE, self._params(device=device, port=port,
                                                      exclude=json.dumps(list(exclude)))).fetchall()
        return [_record(row) for row in rows]

    def claim(self, worker: WorkerId, lease: float, device: str | None = None, port: str | None = None,
              exclude: Sequence[int] = ()) -> Claim | None:
        if not self.path.exists():
            return None
        params = self._params(device=device, port=port, exclude=json.dumps(list(exclude)))
        with self._write() as db:
            row = db.execute(f"{_RUNNABLE} LIMIT 1", params | {"now": time.time()}).fetchone()
            if row is None:
                return None
            job = _record(row)
            self._set(db, job.id, state="running", worker=str(worker), worker_host=worker.host,
                      worker_pid=worker.pid, lease_expires=time.time() + lease, attempts=job.attempts + 1,
                      cancel_requested=0, reason=None)
            what = f"resumed at byte {job.acked_bytes} of {job.program_bytes}" if job.acked_bytes else "started"
            self._event(db, job.id, "started", f"{what} by worker {worker} (attempt {job.attempts + 1})")
            job = self._get(db, job.id)
        try:
            return Claim(job, self.snapshot(job.id))
        except FoldfabError as exc:  # damaged: the worker fails the job (and says so), not itself
            return Claim(job, None, str(exc))

    def heartbeat(self, job_id: int, worker: WorkerId, lease: float, acked_bytes: int | None = None,
                  progress: str | None = None, pauses_done: int | None = None,
                  drawn: tuple[float, float] | None = None) -> Control:
        with self._write() as db:
            owned = self._owned(db, job_id, worker)
            if owned is None:
                return Control("lost", False, True)
            values = _given(acked_bytes=acked_bytes, progress=progress, pauses_done=pauses_done, drawn=drawn)
            self._set(db, job_id, lease_expires=time.time() + lease, **values)
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
            if self._owned(db, job_id, worker) is None:
                return False
            values = _given(acked_bytes=acked_bytes, pauses_done=pauses_done, progress=progress, drawn=drawn)
            self._set(db, job_id, state=state, worker=None, lease_expires=None, worker_host=None,
                      worker_pid=None, cancel_requested=0, reason=None if state == "done" else message,
                      **values)
            self._event(db, job_id, state, message)
            return True


def _rollback(db: sqlite3.Connection) -> None:
    """Roll back the open transaction, if any: SQLite has rolled it back itself when a commit
    failed for a full disk, and a second rollback would replace that error with its own."""
    if db.in_transaction:
        db.execute("ROLLBACK")


def _job_id(job_id: int) -> int:
    """``job_id`` as SQLite takes it: ids beyond its integers (no such job) as -1."""
    return job_id if -MAX_JOB_ID <= job_id <= MAX_JOB_ID else -1


def _given(drawn: tuple[float, float] | None = None, **values) -> dict:
    """The values that are not None, as columns (``drawn``: drawn_mm and drawn_total_mm)."""
    if drawn is not None:
        values.update(drawn_mm=drawn[0], drawn_total_mm=drawn[1])
    return {key: value for key, value in values.items() if value is not None}


def _record(row: tuple) -> JobRecord:
    values = list(row)
    values[17] = bool(values[17])  # cancel_requested
    return JobRecord(*values)
