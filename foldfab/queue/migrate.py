"""Moving a queue's jobs into another queue (an SQLite file's into a PostgreSQL server's, when a
room of plotters outgrows one machine): :func:`move_jobs`.

Every job moves with its snapshot, state, progress (a half-drawn sheet resumes where it was on the
same plotter) and log, under new ids in the target.  Nothing moves while a worker holds a job of
the source: a job is never in two queues at once with a plotter drawing it.  The target gets
every job in one transaction, then the source loses them in one; the columns are those of
:mod:`foldfab.queue.schema`, so both stores are at the same version.
"""

from __future__ import annotations

from foldfab.errors import FoldfabError
from foldfab.queue.limits import ACTIVE
from foldfab.queue.schema import columns
from foldfab.queue.sqlstore import SqlQueueStore


def move_jobs(source: SqlQueueStore, target: SqlQueueStore) -> dict[int, int]:
    """Move every job of ``source`` into ``target``; old id -> new id."""
    if source.location == target.location:
        raise FoldfabError(f"queue {source.location} is both the source and the target; nothing was moved")
    active = [job for job in source.jobs() if job.state in ACTIVE]
    if active:
        raise FoldfabError(f"{len(active)} job(s) of {source.location} are held by workers (first: job "
                           f"{active[0].id}, {active[0].state}); nothing was moved; stop the workers "
                           "(foldfab queue run) of that queue first, or wait until these jobs end")
    if not source.jobs():
        return {}
    snap_cols, job_cols, event_cols = (tuple(c for c in columns(t) if c != "id")
                                       for t in ("snapshots", "jobs", "events"))
    with source._read() as db:
        snapshots = db.execute(f"SELECT id, {', '.join(snap_cols)} FROM snapshots ORDER BY id").fetchall()
        jobs = db.execute(f"SELECT id, {', '.join(job_cols)} FROM jobs ORDER BY id").fetchall()
        events = db.execute(f"SELECT {', '.join(event_cols)} FROM events ORDER BY id").fetchall()
    snapshot_ids, job_ids = {}, {}
    snapshot_at, job_at = job_cols.index("snapshot_id"), event_cols.index("job_id")
    with target._write(create=True) as db:
        for old, *values in snapshots:
            snapshot_ids[old] = db.execute(_insert("snapshots", snap_cols), values).fetchone()[0]
        for old, *values in jobs:
            values[snapshot_at] = snapshot_ids[values[snapshot_at]]
            job_ids[old] = db.execute(_insert("jobs", job_cols), values).fetchone()[0]
        for values in events:
            values = list(values)
            values[job_at] = job_ids[values[job_at]]
            db.execute(_insert("events", event_cols)[:-len(" RETURNING id")], values)
        for new in job_ids.values():
            target._event(db, new, "moved", f"moved from queue {source.location}")
        target._notify(db)
    with source._write() as db:
        held = db.execute("SELECT count(*) FROM jobs WHERE state IN ('running', 'waiting')").fetchone()[0]
        if held:  # a worker claimed one while they were copied: the copies must go
            raise FoldfabError(f"a worker claimed a job of {source.location} while the jobs were copied to "
                               f"{target.location}: remove the copies there (ids {min(job_ids.values())}-"
                               f"{max(job_ids.values())}) and stop the workers first")
        source._delete(db, f"id IN ({', '.join('?' * len(job_ids))})", tuple(job_ids))
    return job_ids


def _insert(table: str, names: tuple[str, ...]) -> str:
    return f"INSERT INTO {table} ({', '.join(names)}) VALUES ({', '.join('?' * len(names))}) RETURNING id"
