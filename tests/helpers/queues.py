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
