"""The queue in one SQLite file: :class:`SqliteQueueStore` (the rules are :mod:`foldfab.queue.sqlstore`'s).

Every change is one ``BEGIN IMMEDIATE`` transaction; the file is in WAL mode (local disks
only: WAL needs shared memory, so not NFS).  Leases compare wall clocks, so hosts that
share a queue need synchronized clocks (NTP).
This module is imported by ``foldfab queue list``: standard library only.
"""

from __future__ import annotations

import json
import os
import sqlite3
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator, Sequence

from foldfab.errors import FoldfabError
from foldfab.queue.schema import migrations
from foldfab.queue.sqlstore import Queries, SqlQueueStore, pid_alive
from foldfab.queue.limits import DEFAULT_WAIT
from foldfab.queue.store import QueueBusy
from foldfab.xdg import foldfab_dir

__all__ = ["MIGRATIONS", "SCHEMA_VERSION", "SqliteQueueStore", "default_queue_path"]


def default_queue_path() -> Path:
    """``$FOLDFAB_QUEUE``, else ``$XDG_DATA_HOME/foldfab/queue.sqlite3`` (default ``~/.local/share``)."""
    if os.environ.get("FOLDFAB_QUEUE"):
        return Path(os.environ["FOLDFAB_QUEUE"])
    return foldfab_dir("XDG_DATA_HOME") / "queue.sqlite3"


STATEMENTS = migrations("sqlite")
MIGRATIONS: tuple[str, ...] = tuple(";\n".join(step) for step in STATEMENTS)
"""Per schema version, the script that brings the version before it there (:mod:`foldfab.queue.schema`)."""
SCHEMA_VERSION = len(MIGRATIONS)
QUERIES = Queries("NOT foldfab_pid_alive(j.worker_pid)", "j.id NOT IN (SELECT value FROM json_each(:exclude))",
                  "INDEXED BY jobs_by_claim_order")


class SqliteQueueStore(SqlQueueStore):
    """The queue in one SQLite file in WAL mode, shared by threads, processes and hosts' workers
    (on a local disk).  ``wait``: seconds to wait for another writer before giving up."""

    queries = QUERIES

    def __init__(self, path: str | os.PathLike, wait: float = DEFAULT_WAIT):
        super().__init__()
        self.path = Path(path)
        self.location = str(self.path)
        self.wait = wait
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
                db.create_function("foldfab_pid_alive", 1, pid_alive)
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
                for statement in STATEMENTS[step]:
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

    def _exists(self) -> bool:
        return self.path.exists()

    def _exclude(self, ids: Sequence[int]) -> str:
        return json.dumps(list(ids))

    def close(self) -> None:
        """Close the connection (the file stays)."""
        with self._lock:
            if self._db is not None:
                self._db.close()
                self._db = None


def _rollback(db: sqlite3.Connection) -> None:
    """Roll back the open transaction, if any: SQLite has rolled it back itself when a commit
    failed for a full disk, and a second rollback would replace that error with its own."""
    if db.in_transaction:
        db.execute("ROLLBACK")
