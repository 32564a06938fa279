"""The queue's stores: ``store`` is each of them in turn (SQLite, and PostgreSQL on the session's
real server), so one suite checks that both keep the same promises; ``sqlite_store`` is for what
only an SQLite file has (its locks, permissions and damage)."""

import pytest

from foldfab.queue.postgres import PostgresQueueStore
from foldfab.queue.sqlite import SqliteQueueStore

STORES = ["sqlite", "postgres"]


@pytest.fixture()
def sqlite_store(tmp_path):
    store = SqliteQueueStore(tmp_path / "queue.sqlite3", wait=2.0)
    yield store
    store.close()


@pytest.fixture()
def postgres_store(postgres_server):
    store = PostgresQueueStore(postgres_server.new_database(), wait=10.0)
    yield store
    store.close()


@pytest.fixture(params=STORES)
def store(request):
    return request.getfixturevalue(f"{request.param}_store")
