"""Where the queue is: an SQLite file (the default) or a PostgreSQL server, chosen by
:func:`open_queue` from one string, so the worker, the command line and the studio never know
which store is behind it.  Standard library only (``foldfab queue list`` imports it)."""

from __future__ import annotations

import os

from foldfab.queue.postgres import is_postgres_url, redact
from foldfab.queue.sqlite import SqliteQueueStore, default_queue_path
from foldfab.queue.limits import DEFAULT_WAIT
from foldfab.queue.store import QueueStore


def queue_location(location: str | os.PathLike | None = None) -> str:
    """``location``, else ``$FOLDFAB_QUEUE``, else the default SQLite file (a URL kept as given: a
    path would fold its ``//``)."""
    return str(location or os.environ.get("FOLDFAB_QUEUE") or default_queue_path())


def open_queue(location: str | os.PathLike | None = None, wait: float = DEFAULT_WAIT) -> QueueStore:
    """The store for ``location``: ``postgresql://user@host/db`` (or ``postgres://``) is a PostgreSQL
    queue, anything else the path of an SQLite file (:func:`queue_location` for the default)."""
    where = queue_location(location)
    if is_postgres_url(where):
        from foldfab.queue.postgres import PostgresQueueStore

        return PostgresQueueStore(where, wait=wait)
    return SqliteQueueStore(where, wait=wait)


def shown_location(location: str | os.PathLike | None = None) -> str:
    """The queue's location as shown to users (a server's password left out)."""
    return redact(queue_location(location))
