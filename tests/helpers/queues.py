"""Reaching under a queue store, as a test does to play a dead worker or a damaged row."""

from __future__ import annotations

import sqlite3


def raw_sql(store, sql: str, params: tuple = ()) -> list[tuple]:
    """Run portable SQL (``?`` parameters) on the store's database, committed; the rows it returns."""
    if hasattr(store, "path"):
        with sqlite3.connect(store.path) as db:
            return db.execute(sql, params).fetchall()
    import psycopg

    from foldfab.queue.postgres import translate

    with psycopg.connect(store.url, autocommit=True) as db:
        cursor = db.execute(translate(sql), params)
        return cursor.fetchall() if cursor.description else []


FILL = """INSERT INTO jobs (snapshot_id, port, priority, copy, copies, state, created, updated, drawn_total_mm)
    WITH RECURSIVE n(i) AS (SELECT CAST(? AS INTEGER) UNION ALL SELECT i + 1 FROM n WHERE i < ?)
    SELECT ?, 'sim://p' || (i - i / ? * ?), i - i / 3 * 3, 1, 1,
           CASE WHEN i - i / 10 * 10 < 7 THEN 'done' WHEN i - i / 10 * 10 = 7 THEN 'cancelled' ELSE 'queued' END,
           ?, ?, 10.0 FROM n"""


def fill_jobs(store, snapshot, count: int, plotters: int = 64) -> None:
    """``count`` jobs of ``snapshot`` on ``plotters`` ports at once, in one statement (a big queue
    for benchmarks and query plans, in seconds; no events): 7 in 10 done, 1 cancelled, 2 queued."""
    import time

    from foldfab.queue.records import NewJob

    (first,) = store.add([NewJob(snapshot, "sim://p1")])
    (snapshot_id,) = raw_sql(store, "SELECT snapshot_id FROM jobs WHERE id = ?", (first,))[0]
    now = time.time()
    raw_sql(store, FILL, (first + 1, first + count - 1, snapshot_id, plotters, plotters, now, now))
    if not hasattr(store, "path"):
        raw_sql(store, "ANALYZE")  # the statistics PostgreSQL's autovacuum gathers on a long-lived queue
