"""One schema for both stores, and jobs moved from an SQLite queue into a PostgreSQL one."""

from __future__ import annotations

import sqlite3
from pathlib import Path

from foldfab.devices import load_device
from foldfab.programs.program import PauseMark, Program
from foldfab.queue.records import NewJob, WorkerId
from foldfab.queue.snapshot import make_snapshot
from foldfab.queue.schema import VERSION, columns, migrations
from helpers.cli import run as run_cli
from helpers.queues import raw_sql


def snapshot(name: str):
    device = load_device("graphtec-ce6000")
    program = Program("IN;SP1;PU0,0;PD400,400;PU0,0;PD0,400;SP0;", "hpgl", device.name, (),
                      (PauseMark(20, 1, "flip the sheet"),))
    return make_snapshot(Path("job.toml"), "[design]\n", name, device, program)


def test_both_stores_have_the_schema_of_the_one_description(sqlite_store, postgres_store):
    for store in (sqlite_store, postgres_store):
        store.add([NewJob(snapshot("x"), "sim://a")])
    assert [len(step) for step in migrations("sqlite")] == [len(step) for step in migrations("postgres")]
    for table in ("snapshots", "jobs", "events"):
        with sqlite3.connect(sqlite_store.path) as db:
            assert tuple(row[1] for row in db.execute(f"PRAGMA table_info({table})")) == columns(table)
        assert tuple(name for (name,) in raw_sql(
            postgres_store, "SELECT column_name FROM information_schema.columns WHERE table_name = ? "
            "ORDER BY ordinal_position", (table,))) == columns(table)
    assert raw_sql(postgres_store, "SELECT version FROM foldfab_schema") == [(VERSION,)]
    with sqlite3.connect(sqlite_store.path) as db:
        assert db.execute("PRAGMA user_version").fetchone() == (VERSION,)


def test_queue_migrate_moves_every_job_with_its_progress_and_log(sqlite_store, postgres_store, capsys):
    old, new = sqlite_store, postgres_store
    new.add([NewJob(snapshot("already there"), "sim://z")])
    old.add([NewJob(snapshot("a"), "sim://a", 3, 2), NewJob(snapshot("b"), "sim://b")])
    worker = WorkerId.current()
    claim = old.claim(worker, 30)
    old.heartbeat(claim.job.id, worker, 30, acked_bytes=12, progress="stroke 1 of 2", drawn=(10.0, 20.0))
    old.finish(claim.job.id, worker, "interrupted", "cable pulled")
    before = {j.id: j for j in old.jobs()}
    logs = {i: [(e.kind, e.message) for e in old.events(i)] for i in before}
    snaps = {i: old.snapshot(i) for i in before}
    held = old.claim(worker, 30, port="sim://b")  # a worker holds a job: nothing moves
    code, out, err = run_cli(capsys, "queue", "migrate", str(old.path), "--queue", new.url)
    assert code == 2 and "held by workers" in err and "nothing was moved" in err
    assert len(new.jobs()) == 1 and len(old.jobs()) == 3
    old.finish(held.job.id, worker, "failed", "error 3")
    before[held.job.id] = old.job(held.job.id)
    logs[held.job.id] = [(e.kind, e.message) for e in old.events(held.job.id)]
    code, out, err = run_cli(capsys, "queue", "migrate", str(old.path), "--queue", new.url)
    assert code == 0 and "moved 3 jobs" in out and "now jobs 2-4" in out, err
    assert old.jobs() == [] and raw_sql(old, "SELECT count(*) FROM snapshots") == [(0,)]
    moved = new.jobs()[1:]
    for job, (old_id, was) in zip(moved, sorted(before.items())):
        keep = ("name", "port", "priority", "copy", "copies", "state", "acked_bytes", "progress", "drawn_mm",
                "drawn_total_mm", "reason", "attempts", "created")
        assert [getattr(job, k) for k in keep] == [getattr(was, k) for k in keep]
        assert new.snapshot(job.id) == snaps[old_id]
        assert [(e.kind, e.message) for e in new.events(job.id)][:-1] == logs[old_id]
        assert new.events(job.id)[-1].kind == "moved"
    # the interrupted sheet resumes where it was, on its plotter
    again = new.claim(worker, 30)
    assert (again.job.name, again.job.acked_bytes, again.job.port) == ("a", 12, "sim://a")
