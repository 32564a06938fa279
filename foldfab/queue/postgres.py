"""The queue on a PostgreSQL server: :class:`PostgresQueueStore`, for a farm of hosts sharing one queue.

The rules are :mod:`foldfab.queue.sqlstore`'s; this module adds what a server needs:

- connections from a psycopg 3 pool (``psycopg_pool``), each checked before use, so a server
  restart costs one failed operation (reported as :class:`~foldfab.queue.store.QueueBusy`, a
  passing condition: the worker's heartbeat tries again) and no more;
- claims that never wait for one another: the next runnable job is read ``FOR UPDATE SKIP LOCKED``
  (a job another worker is claiming is passed over), then its plotter is taken with a
  transaction-level advisory lock on the port (tried, not waited for: a plotter another worker
  is claiming on is passed over too) and the job checked again, so one plotter still runs one
  job at a time and a half-drawn sheet still holds its plotter, across hosts;
- ``NOTIFY foldfab_queue`` when a job may have become runnable (added, retried, cancelled,
  removed, finished, its worker's lease expired), which wakes workers waiting in
  :meth:`PostgresQueueStore.wait_for_work` (``LISTEN``) at once; their poll is the fallback;
- the schema of :mod:`foldfab.queue.schema`, migrated under an advisory lock, its version in
  the table ``foldfab_schema``.

Leases compare the hosts' wall clocks: the hosts of a farm need synchronized clocks (NTP).
psycopg is imported only when a PostgreSQL queue is used (``pip install 'foldfab[postgres]'``).
"""

from __future__ import annotations

import logging
import re
import threading
import time
from contextlib import contextmanager
from functools import lru_cache
from typing import Any, Iterator, Sequence

from foldfab.errors import FoldfabError
from foldfab.queue.schema import VERSION, migrations
from foldfab.queue.sqlstore import Queries, SqlQueueStore, pid_alive
from foldfab.queue.limits import DEFAULT_WAIT
from foldfab.queue.store import QueueBusy

CHANNEL = "foldfab_queue"
LOCK_CLASS = 0x466F  # advisory locks: (LOCK_CLASS, hashtext(port)) a plotter, (LOCK_CLASS + 1, 0) the schema
CLAIM_TRIES = 100
"""Most candidates one claim looks at (a candidate fails when another worker took its plotter)."""
POOL_SIZE = 4
QUERIES = Queries("j.worker_pid = ANY(:dead)", "j.id <> ALL(:exclude)")


def is_postgres_url(location: str) -> bool:
    """Whether a queue location names a PostgreSQL server (else it is an SQLite file)."""
    return location.startswith(("postgresql://", "postgres://"))


def redact(url: str) -> str:
    """The URL without its password (for messages and listings)."""
    return re.sub(r"^(\w+://[^:/@?]*):[^@/?]*@", r"\1:***@", url)


@lru_cache(maxsize=256)
def translate(sql: str) -> str:
    """Portable SQL (``?``, ``:name``) in psycopg's parameter style (``%s``, ``%(name)s``)."""
    return re.sub(r"(?<![:\w]):(\w+)", r"%(\1)s", sql.replace("?", "%s"))


class _Transaction:
    """A psycopg connection inside a transaction, as :class:`SqlQueueStore` uses it."""

    def __init__(self, conn: Any):
        self.conn = conn
        self.dead: list[int] | None = None

    def execute(self, sql: str, params: Sequence | dict = ()) -> Any:
        return self.conn.execute(translate(sql), params)

    def executemany(self, sql: str, rows: Sequence) -> None:
        if rows:
            self.conn.cursor().executemany(translate(sql), rows)


def _psycopg():
    try:
        import psycopg
        import psycopg_pool
    except ImportError:
        raise FoldfabError("a PostgreSQL queue needs psycopg 3 and psycopg-pool: pip install 'foldfab[postgres]' "
                           "(or give --queue the path of an SQLite file)") from None
    return psycopg, psycopg_pool


class PostgresQueueStore(SqlQueueStore):
    """The queue in a PostgreSQL database (``url``: ``postgresql://user@host/db``), shared by every
    host's workers.  ``wait``: seconds to wait for a connection before giving up."""

    queries = QUERIES
    for_update = "FOR UPDATE OF j"
    skip_locked = "FOR UPDATE OF j SKIP LOCKED"
    survives_outages = True

    def __init__(self, url: str, wait: float = DEFAULT_WAIT):
        super().__init__()
        self.url = url
        self.location = redact(url)
        self.wait = wait
        self._pool: Any = None
        self._listener: Any = None
        self._pool_lock = threading.Lock()

    # -- connections, errors, migrations

    def _connections(self) -> Any:
        with self._pool_lock:
            if self._pool is None:
                psycopg, psycopg_pool = _psycopg()
                logging.getLogger("psycopg.pool").addHandler(logging.NullHandler())  # errors: ours, one line
                logging.getLogger("psycopg.pool").propagate = False
                pool = psycopg_pool.ConnectionPool(
                    self.url, min_size=1, max_size=POOL_SIZE, open=False, timeout=max(self.wait, 0.1),
                    kwargs={"cursor_factory": psycopg.ClientCursor}, check=psycopg_pool.ConnectionPool.check_connection,
                    name="foldfab-queue")
                with self._errors():
                    pool.open()
                    try:
                        with pool.connection() as conn, conn.transaction():
                            self._migrate(_Transaction(conn))
                    except BaseException:
                        pool.close()
                        raise
                self._pool = pool
            return self._pool

    def _migrate(self, db: _Transaction) -> None:
        db.execute("SELECT pg_advisory_xact_lock(?, 0)", (LOCK_CLASS + 1,))
        tables = {row[0] for row in db.execute("SELECT tablename FROM pg_tables WHERE schemaname = current_schema()")}
        if "foldfab_schema" not in tables and tables & {"jobs", "snapshots", "events"}:
            raise FoldfabError(f"database {self.location} has tables named as a foldfab queue's but is not one; "
                               "give --queue another database")
        db.execute("CREATE TABLE IF NOT EXISTS foldfab_schema (version INTEGER NOT NULL)")
        row = db.execute("SELECT version FROM foldfab_schema").fetchone()
        version = row[0] if row else 0
        if version > VERSION:
            raise FoldfabError(f"queue {self.location} has schema version {version}, but this foldfab knows only "
                               f"up to {VERSION}: upgrade foldfab, or choose another queue with --queue")
        for step in migrations("postgres")[version:]:
            for statement in step:
                db.execute(statement)
        if row is None:
            db.execute("INSERT INTO foldfab_schema (version) VALUES (?)", (VERSION,))
        elif version < VERSION:
            db.execute("UPDATE foldfab_schema SET version = ?", (VERSION,))

    @contextmanager
    def _errors(self) -> Iterator[None]:
        """psycopg's errors as one line that names the server and what to do; a server that cannot
        be reached (down, restarting, the network gone) or a lost race is :class:`QueueBusy`."""
        psycopg, psycopg_pool = _psycopg()
        try:
            yield
        except psycopg_pool.PoolTimeout:
            raise QueueBusy(f"queue server {self.location} cannot be reached ({self._why_unreachable()}); nothing "
                            "was changed; check that the server runs and the network, then try again") from None
        except psycopg.OperationalError as exc:
            raise QueueBusy(f"queue server {self.location}: {_first_line(exc)}; nothing was changed; try again "
                            "(the server may be restarting or unreachable)") from None
        except psycopg.Error as exc:
            raise FoldfabError(f"queue {self.location}: {_first_line(exc)}; nothing was changed") from None

    def _why_unreachable(self) -> str:
        """Why a connection cannot be made, in the server's or the network's words."""
        psycopg, _ = _psycopg()
        try:
            psycopg.connect(self.url, connect_timeout=max(int(self.wait), 2)).close()
        except psycopg.Error as exc:
            return _first_line(exc)
        return f"no connection free within {self.wait:g} s"

    @contextmanager
    def _transaction(self, write: bool) -> Iterator[_Transaction]:
        pool = self._connections()
        with self._errors(), pool.connection() as conn, conn.transaction():
            db = _Transaction(conn)
            if write:
                self._expire(db)
            yield db

    def _read(self) -> Any:
        return self._transaction(write=False)

    def _write(self, create: bool = False) -> Any:
        return self._transaction(write=True)

    def close(self) -> None:
        """Close the connections (the queue stays on the server)."""
        with self._pool_lock:
            if self._pool is not None:
                self._pool.close()
                self._pool = None
            if self._listener is not None:
                self._listener.close()
                self._listener = None

    # -- the dialect

    def _exclude(self, ids: Sequence[int]) -> list[int]:
        return [int(i) for i in ids]

    def _dead_pids(self, db: _Transaction) -> list[int]:
        """Processes on this host that hold jobs but are gone (once per transaction)."""
        if db.dead is None:
            rows = db.execute("SELECT DISTINCT worker_pid FROM jobs WHERE state IN ('running', 'waiting') "
                              "AND worker_host = ? AND worker_pid IS NOT NULL", (self._host,)).fetchall()
            db.dead = [pid for (pid,) in rows if not pid_alive(pid)]
        return db.dead

    def _next_runnable(self, db: _Transaction, params: dict) -> tuple | None:
        skipped = list(params["exclude"])
        for _ in range(CLAIM_TRIES):
            row = db.execute(f"SELECT j.id, COALESCE(:port, j.port) FROM jobs j "  # the port the job runs at
                             f"JOIN snapshots s ON s.id = j.snapshot_id "
                             f"{self.queries.runnable_where} {self.queries.claim_order} LIMIT 1 {self.skip_locked}",
                             params | {"exclude": skipped}).fetchone()
            if row is None:
                return None
            if not db.execute("SELECT pg_try_advisory_xact_lock(?, hashtext(?))", (LOCK_CLASS, row[1])).fetchone()[0]:
                skipped.append(row[0])  # another worker is claiming on that plotter now: never wait for it
                continue
            again = db.execute(f"{self.queries.select_jobs} {self.queries.runnable_where} AND j.id = :id",
                               params | {"exclude": skipped, "id": row[0]}).fetchone()
            if again is not None:
                return again
            skipped.append(row[0])  # another worker took its plotter meanwhile
        return None

    def _lock_port(self, db: _Transaction, port: str) -> None:
        db.execute("SELECT pg_advisory_xact_lock(?, hashtext(?))", (LOCK_CLASS, port))

    def _notify(self, db: _Transaction) -> None:
        db.execute(f"NOTIFY {CHANNEL}")

    def wait_for_work(self, timeout: float, stop: threading.Event) -> None:
        """Wait for a ``NOTIFY`` (a job may have become runnable), ``stop`` or ``timeout`` s.  The first
        call starts listening and returns at once (a job added just before is not missed); a lost
        connection is noticed and this falls back to waiting out ``timeout``."""
        psycopg, _ = _psycopg()
        deadline = time.monotonic() + timeout
        try:
            if self._listener is None:
                self._listener = psycopg.connect(self.url, autocommit=True, connect_timeout=max(int(timeout), 2))
                self._listener.execute(f"LISTEN {CHANNEL}")
                return
            while not stop.is_set() and (left := deadline - time.monotonic()) > 0:
                if any(True for _ in self._listener.notifies(timeout=min(left, 0.5), stop_after=1)):
                    for _ in self._listener.notifies(timeout=0.01):  # the rest already queued
                        pass
                    return
        except psycopg.Error:
            if self._listener is not None:
                self._listener.close()
                self._listener = None
            stop.wait(max(deadline - time.monotonic(), 0))


def _first_line(exc: BaseException) -> str:
    return (str(exc).strip().splitlines() or [type(exc).__name__])[0]
