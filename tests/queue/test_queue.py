"""The job queue's storage: snapshots, states, claims, leases, schema migrations and file errors."""

from __future__ import annotations

import json
import multiprocessing
import os
import shutil
import sqlite3
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from hypothesis import settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, precondition, rule

from foldfab.cli import main
from foldfab.devices import load_device
from foldfab.errors import FoldfabError
from foldfab.programs.program import PauseMark, Program
from foldfab.queue.records import NewJob, WorkerId
from foldfab.queue.snapshot import make_snapshot
from foldfab.queue.sqlite import SqliteQueueStore
from foldfab.queue.location import open_queue
from foldfab.queue.snapshot import load_snapshot_device
from foldfab.queue.sqlite import MIGRATIONS, SCHEMA_VERSION
from helpers import HEXAGON, ROOT
from helpers.cli import run as run_cli
from helpers.queues import raw_sql


def snapshot(text: str = "IN;SP1;PU0,0;PD400,400;SP0;", name: str = "test job", pauses=()):
    """A snapshot of a hand-written program (no geometry needed to test storage)."""
    device = load_device("graphtec-ce6000")
    program = Program(text, "hpgl", device.name, (), tuple(pauses))
    return make_snapshot(Path("job.toml"), "[design]\n", name, device, program)


def fill(store, ports: list[str], per_port: int) -> list[int]:
    return store.add([NewJob(snapshot(), port, 0, per_port) for port in ports])


# --- states and transitions ------------------------------------------------------------------


def test_add_list_and_snapshot_round_trip(store):
    snap = snapshot(pauses=[PauseMark(12, 1, "flip the sheet")])
    ids = store.add([NewJob(snap, "sim://a", 2, 3)])
    assert ids == [1, 2, 3]
    jobs = store.jobs()
    assert [(j.id, j.copy, j.copies, j.state, j.priority) for j in jobs] == \
        [(1, 1, 3, "queued", 2), (2, 2, 3, "queued", 2), (3, 3, 3, "queued", 2)]
    assert store.snapshot(2) == snap  # program text, sections, pauses and both texts
    assert load_snapshot_device(snap).name == "graphtec-ce6000"
    assert [e.kind for e in store.events(1)] == ["queued"]
    assert store.jobs("running") == []


def test_a_queued_job_knows_its_length_before_it_runs(store, capsys):
    """Issue 18: ``queue list --json`` showed drawn_total_mm 0.0 for a queued job whose length is known at add."""
    store.add([NewJob(snapshot("IN;SP1;PU0,0;PD400,300;PU0,0;PD0,400;SP0;"), "sim://a", 0, 2)])
    code, out, _ = run_cli(capsys, "queue", "list", "--json", "--queue", store.location)
    listed = json.loads(out)
    assert code == 0 and [j["state"] for j in listed] == ["queued"] * 2
    assert [j["drawn_total_mm"] for j in listed] == [pytest.approx(12.5 + 10.0)] * 2  # 40 units/mm: 500 + 400 units
    assert [j["drawn_mm"] for j in listed] == [0, 0] and store.job(1).percent == 0


def test_claim_order_priority_then_arrival_and_one_job_per_port(store):
    store.add([NewJob(snapshot(name="low"), "sim://a", 0, 2), NewJob(snapshot(name="high"), "sim://a", 5),
               NewJob(snapshot(name="other port"), "sim://b", 1)])
    worker = WorkerId.current()
    first = store.claim(worker, 30)
    assert (first.job.id, first.job.name, first.job.state) == (3, "high", "running")
    second = store.claim(worker, 30)
    assert second.job.port == "sim://b"  # sim://a is busy
    assert store.claim(worker, 30) is None
    store.finish(first.job.id, worker, "done", "done")
    assert store.claim(worker, 30).job.id == 1
    assert store.claim(worker, 30, device="graphtec-ce6000") is None
    assert store.runnable() == []


def test_interrupted_job_goes_first_and_blocks_its_plotter(store):
    fill(store, ["sim://a"], 2)
    worker = WorkerId.current()
    claim = store.claim(worker, 30)
    store.heartbeat(claim.job.id, worker, 30, acked_bytes=7, progress="stroke 1/2")
    store.finish(claim.job.id, worker, "interrupted", "serial port vanished")
    store.add([NewJob(snapshot(), "sim://a", 9)])
    assert [j.id for j in store.runnable()] == [1]  # the half-drawn sheet is on the plotter
    again = store.claim(worker, 30)
    assert (again.job.id, again.job.acked_bytes, again.job.attempts) == (1, 7, 2)
    assert "resumed at byte 7" in store.events(1)[-1].message


@pytest.mark.parametrize("end", ["interrupted", "failed", "cancelled"])
def test_a_job_retried_to_resume_keeps_its_plotter_and_goes_first(store, end):
    """retry without --restart of a job partly drawn: its sheet is on the plotter, so nothing
    else runs there first, whatever its priority."""
    fill(store, ["sim://a"], 1)
    worker = WorkerId.current()
    claim = store.claim(worker, 30)
    store.heartbeat(claim.job.id, worker, 30, acked_bytes=7)
    store.finish(claim.job.id, worker, end, "stopped")
    store.add([NewJob(snapshot(), "sim://a", 5), NewJob(snapshot(), "sim://b", 9)])
    job = store.retry(1)
    assert (job.state, job.acked_bytes) == ("queued", 7)
    assert [j.id for j in store.runnable()] == [1, 3]  # job 2 waits: the half-drawn sheet is on sim://a
    assert store.runnable(exclude=[1]) == [store.job(3)]  # also while a worker holds job 1 back
    assert store.claim(worker, 30, port="sim://a").job.id == 1
    assert store.claim(worker, 30, port="sim://a") is None
    store.finish(1, worker, "done", "finished")
    assert store.claim(worker, 30, port="sim://a").job.id == 2


def test_a_job_retried_from_the_start_does_not_hold_its_plotter(store):
    fill(store, ["sim://a"], 1)
    worker = WorkerId.current()
    claim = store.claim(worker, 30)
    store.heartbeat(claim.job.id, worker, 30, acked_bytes=7)
    store.finish(claim.job.id, worker, "interrupted", "serial port vanished")
    store.add([NewJob(snapshot(), "sim://a", 5)])
    assert store.retry(1, restart=True).acked_bytes == 0  # a new sheet: priority decides
    assert [j.id for j in store.runnable()] == [2, 1]


def test_cancel_queued_running_and_waiting(store):
    fill(store, ["sim://a", "sim://b"], 2)
    assert store.cancel(2).state == "cancelled"
    worker = WorkerId.current()
    claim = store.claim(worker, 30)
    job = store.cancel(claim.job.id)
    assert job.state == "running" and job.cancel_requested
    control = store.heartbeat(claim.job.id, worker, 30)
    assert control.cancel_requested and not control.lost
    assert store.finish(claim.job.id, worker, "cancelled", "cancelled: pen up, parked at byte 5")
    assert store.job(claim.job.id).reason == "cancelled: pen up, parked at byte 5"
    waiting = store.claim(worker, 30)
    assert store.wait_at_pause(waiting.job.id, worker, "flip the sheet").state == "waiting"
    assert store.cancel(waiting.job.id).cancel_requested
    with pytest.raises(FoldfabError, match="is cancelled, nothing to cancel; remove it"):
        store.cancel(2)


def test_continue_retry_remove_clear(store):
    fill(store, ["sim://a"], 3)
    worker = WorkerId.current()
    claim = store.claim(worker, 30)
    with pytest.raises(FoldfabError, match="not waiting at a pause"):
        store.continue_job(claim.job.id, "test")
    store.wait_at_pause(claim.job.id, worker, "flip the sheet")
    assert store.heartbeat(claim.job.id, worker, 30).state == "waiting"
    job = store.continue_job(claim.job.id, "test")
    assert (job.state, job.pauses_done) == ("running", 0)  # the worker records it once it goes on
    assert store.heartbeat(claim.job.id, worker, 30, pauses_done=1).state == "running"
    assert store.job(claim.job.id).pauses_done == 1
    with pytest.raises(FoldfabError, match="cancel it first"):
        store.remove(claim.job.id)
    store.heartbeat(claim.job.id, worker, 30, acked_bytes=10)
    store.finish(claim.job.id, worker, "failed", "plotter error 3 at byte 10")
    assert store.job(1).reason == "plotter error 3 at byte 10"
    with pytest.raises(FoldfabError, match="only failed, cancelled or interrupted"):
        store.retry(2)
    assert (store.retry(1).state, store.job(1).acked_bytes) == ("queued", 10)  # resumes by default
    store.cancel(1)
    job = store.retry(1, restart=True)
    assert (job.state, job.acked_bytes, job.pauses_done) == ("queued", 0, 0)
    claim = store.claim(worker, 30)
    store.finish(claim.job.id, worker, "done", "finished")
    assert store.clear(["done"]) == 1
    store.remove(2)
    assert [j.id for j in store.jobs()] == [3]
    with pytest.raises(FoldfabError, match="no job 2"):
        store.events(2) or store.job(2)
    assert store.snapshot(3)  # the shared snapshot stays while a copy uses it
    store.remove(3)
    assert raw_sql(store, "SELECT count(*) FROM snapshots") == [(0,)]
    assert raw_sql(store, "SELECT count(*) FROM events") == [(0,)]


def test_queue_move_takes_an_interrupted_job_to_another_plotter_only_when_told(store, capsys):
    fill(store, ["sim://a"], 1)
    worker = WorkerId.current()
    claim = store.claim(worker, 30)
    store.heartbeat(claim.job.id, worker, 30, acked_bytes=7)
    store.finish(claim.job.id, worker, "interrupted", "host lost power")
    assert store.claim(worker, 30, port="sim://b") is None  # a half-drawn sheet never moves by itself
    with pytest.raises(SystemExit) as stop:
        main(["queue", "move", "1", "--queue", where(store)])
    assert stop.value.code == 2 and "one of the arguments --port --plotter is required" in capsys.readouterr().err
    code, out, _ = run_cli(capsys, "queue", "move", "1", "--port", "sim://b", "--queue", where(store))
    assert code == 0 and "resumes at byte 7" in out
    assert (store.job(1).port, store.job(1).acked_bytes) == ("sim://b", 7)
    assert store.claim(worker, 30, port="sim://a") is None
    assert store.claim(worker, 30, port="sim://b").job.id == 1


def test_worker_loses_a_job_it_no_longer_holds(store):
    fill(store, ["sim://a"], 1)
    worker, other = WorkerId.current(), WorkerId.current()
    claim = store.claim(worker, 30)
    assert store.heartbeat(claim.job.id, other, 30).lost
    assert not store.finish(claim.job.id, other, "done", "not mine")
    assert store.job(claim.job.id).state == "running"


# --- leases -----------------------------------------------------------------------------------


def lease_over(store, timeout: float = 60.0) -> None:
    """Wait until the only job's 0.2 s lease has run out, as the queue sees it (not for a time)."""
    deadline = time.monotonic() + timeout
    while store.jobs()[0].state == "running":
        assert time.monotonic() < deadline, "the lease never ran out"
        time.sleep(0.02)  # poll interval


def test_expired_lease_interrupts_and_the_next_claim_resumes(store):
    fill(store, ["sim://a"], 1)
    dead, alive = WorkerId.current(), WorkerId.current()
    claim = store.claim(dead, 0.2)
    store.heartbeat(claim.job.id, dead, 0.2, acked_bytes=9, progress="stroke 1/2")
    lease_over(store)
    listed = store.jobs()[0]  # reads show what the next write will make of it, without writing
    assert listed.state == "interrupted" and "stopped renewing" in listed.reason
    assert store.jobs("interrupted") == [listed]
    again = store.claim(alive, 30)
    assert (again.job.id, again.job.acked_bytes, again.job.worker) == (claim.job.id, 9, str(alive))
    kinds = [e.kind for e in store.events(claim.job.id)]
    assert kinds == ["queued", "started", "interrupted", "started"]
    assert "lease expired" in store.events(claim.job.id)[2].message
    assert store.heartbeat(claim.job.id, dead, 30).lost  # the old worker cannot take it back


def test_worker_process_gone_on_this_machine_is_noticed_before_its_lease_ends(store):
    fill(store, ["sim://a"], 1)
    process = subprocess.Popen([sys.executable, "-c", "pass"])
    process.wait()
    ghost = WorkerId(WorkerId.current().host, process.pid, "ghost")
    store.claim(ghost, 3600)
    assert store.jobs()[0].state == "interrupted"
    claim = store.claim(WorkerId.current(), 30)
    assert claim is not None and "no longer exists" in store.events(claim.job.id)[2].message


def test_cancel_requested_then_worker_dies_ends_cancelled(store):
    fill(store, ["sim://a"], 1)
    worker = WorkerId.current()
    claim = store.claim(worker, 0.2)
    store.cancel(claim.job.id)
    lease_over(store)
    assert store.jobs()[0].state == "cancelled"
    assert store.claim(worker, 30) is None
    assert store.job(claim.job.id).state == "cancelled"


def where(store) -> str:
    """What --queue and open_queue take for ``store``."""
    return getattr(store, "url", None) or str(store.path)


# --- racing workers ---------------------------------------------------------------------------


def _drain(location: str, results, ports_in_use, lock, delay: float = 0.0) -> None:
    """A minimal worker: claim, 'plot', finish, until nothing is left; record what it ran."""
    store = open_queue(location, wait=30)
    worker = WorkerId.current()
    while True:
        claim = store.claim(worker, 30)
        if claim is None:
            if not store.runnable() and not [j for j in store.jobs() if j.state in ("running", "waiting")]:
                break
            time.sleep(0.01)
            continue
        with lock:
            assert claim.job.port not in ports_in_use, "two jobs on one plotter"
            ports_in_use.append(claim.job.port)
        time.sleep(delay)
        with lock:
            ports_in_use.remove(claim.job.port)
        assert store.finish(claim.job.id, worker, "done", "finished")
        results.append(claim.job.id)
    store.close()


@pytest.mark.filterwarnings("error::pytest.PytestUnhandledThreadExceptionWarning")
def test_threads_racing_run_every_job_exactly_once(store):
    ids = fill(store, [f"sim://p{i}" for i in range(5)], 12)
    results: list[int] = []
    in_use: list[str] = []
    lock = threading.Lock()
    threads = [threading.Thread(target=_drain, args=(where(store), results, in_use, lock, 0.002))
               for _ in range(8)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert sorted(results) == ids
    assert {j.state for j in store.jobs()} == {"done"}
    assert all(j.attempts == 1 for j in store.jobs())


def test_processes_racing_run_every_job_exactly_once(store):
    ids = fill(store, [f"sim://p{i}" for i in range(4)], 15)
    context = multiprocessing.get_context("spawn")
    with context.Manager() as manager:
        results, in_use, lock = manager.list(), manager.list(), manager.Lock()
        processes = [context.Process(target=_drain, args=(where(store), results, in_use, lock, 0.002))
                     for _ in range(4)]
        for process in processes:
            process.start()
        for process in processes:
            process.join(120)
            assert process.exitcode == 0
        assert sorted(results) == ids
    assert [len([e for e in store.events(i) if e.kind == "started"]) for i in ids] == [1] * len(ids)


# --- the file: schema, locks, permissions, damage ---------------------------------------------


def test_upgrade_from_schema_version_1(tmp_path):
    path = tmp_path / "old.sqlite3"
    db = sqlite3.connect(path)
    db.executescript(MIGRATIONS[0])
    db.execute("PRAGMA user_version = 1")
    snap = snapshot()
    from foldfab.queue.snapshot import program_meta

    db.execute("INSERT INTO snapshots (name, job_path, device, program_bytes, program_sha256, program_meta, "
               "job_text, device_text, program) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
               (snap.name, snap.job_path, snap.device, len(snap.program.text), snap.sha256,
                program_meta(snap.program), snap.job_text, snap.device_text, snap.program.text))
    db.execute("INSERT INTO jobs (snapshot_id, port, state, created, updated, acked_bytes) "
               "VALUES (1, 'sim://a', 'interrupted', 0, 0, 4)")
    db.commit()
    db.close()
    store = SqliteQueueStore(path)
    job = store.job(1)
    assert (job.state, job.acked_bytes, job.progress) == ("interrupted", 4, "")
    # no drawn length measured yet: the share done is that of the bytes
    assert (job.drawn_mm, job.drawn_total_mm) == (0, 0)
    assert job.percent == pytest.approx(100 * 4 / len(snap.program.text))
    claim = store.claim(WorkerId.current(), 30)
    assert claim.snapshot == snap and claim.job.acked_bytes == 4
    store.close()
    db = sqlite3.connect(path)
    assert db.execute("PRAGMA user_version").fetchone() == (SCHEMA_VERSION,)
    assert db.execute("PRAGMA journal_mode").fetchone() == ("wal",)
    assert db.execute("SELECT worker_host, worker_pid FROM jobs").fetchone() == (claim.job.worker.split("/")[0],
                                                                                 os.getpid())
    db.close()


def test_newer_schema_and_foreign_files_are_refused(tmp_path):
    newer = tmp_path / "newer.sqlite3"
    with sqlite3.connect(newer) as db:
        db.execute(f"PRAGMA user_version = {SCHEMA_VERSION + 1}")
    with pytest.raises(FoldfabError, match=f"schema version {SCHEMA_VERSION + 1}, but this foldfab knows only up to {SCHEMA_VERSION}: upgrade"):
        SqliteQueueStore(newer).jobs()
    other = tmp_path / "other.sqlite3"
    with sqlite3.connect(other) as db:
        db.execute("CREATE TABLE photos (x)")
    with pytest.raises(FoldfabError, match="not a foldfab queue"):
        SqliteQueueStore(other).jobs()


def test_locked_queue_waits_then_says_so_and_loses_nothing(sqlite_store, capsys):
    store = sqlite_store
    fill(store, ["sim://a"], 2)
    blocker = sqlite3.connect(store.path, isolation_level=None)
    blocker.execute("BEGIN IMMEDIATE")
    started = time.monotonic()
    impatient = SqliteQueueStore(store.path, wait=0.3)
    with pytest.raises(FoldfabError, match=r"is busy: another foldfab kept it locked for more than 0.3 s; "
                                           "nothing was changed"):
        impatient.cancel(1)
    assert time.monotonic() - started >= 0.3
    assert [j.state for j in impatient.jobs()] == ["queued", "queued"]  # readers are not blocked (WAL)
    code, _, err = run_cli(capsys, "queue", "remove", "1", "--queue", str(store.path), "--wait", "0.2")
    assert code == 2 and "is busy" in err and "--wait" in err
    blocker.execute("ROLLBACK")
    blocker.close()
    assert [j.id for j in store.jobs()] == [1, 2]
    assert impatient.cancel(1).state == "cancelled"


def _as_nobody(func, *args) -> None:
    """Run ``func(*args)`` in a child process that cannot write root's files (or in this one when not root)."""
    if os.geteuid() != 0:
        func(*args)
        return
    pid = os.fork()
    if pid == 0:
        code = 1
        try:
            os.setgid(65534)
            os.setuid(65534)
            func(*args)
            code = 0
        finally:
            os._exit(code)
    assert os.waitpid(pid, 0)[1] == 0, "the checks in the unprivileged child failed"


def _read_only_checks(path: Path) -> None:
    store = SqliteQueueStore(path, wait=0.5)
    assert [j.id for j in store.jobs()] == [1]
    try:
        store.cancel(1)
    except FoldfabError as exc:
        assert f"queue file {path} is read-only for you" in str(exc) and "nothing was changed" in str(exc)
    else:
        raise AssertionError("a read-only queue accepted a change")


def test_read_only_queue_file():
    import tempfile

    folder = Path(tempfile.mkdtemp(prefix="foldfab-queue-test-"))  # pytest's folders are private to their owner
    try:
        os.chmod(folder, 0o777)  # a shared folder; the file itself is read-only
        path = folder / "queue.sqlite3"
        store = SqliteQueueStore(path)
        fill(store, ["sim://a"], 1)
        store.close()
        os.chmod(path, 0o444)
        _as_nobody(_read_only_checks, path)
        os.chmod(path, 0o644)
        assert SqliteQueueStore(path).job(1).state == "queued"
    finally:
        shutil.rmtree(folder)


def test_damaged_queue_file_is_reported_and_left_alone(tmp_path, capsys):
    path = tmp_path / "queue.sqlite3"
    path.write_bytes(b"this is not a database, it was overwritten by mistake\n" * 200)
    before = path.read_bytes()
    for args in (["list"], ["show", "1"], ["cancel", "1"], ["add", str(HEXAGON), "--device", "graphtec-ce6000"]):
        code, _, err = run_cli(capsys, "queue", *args, "--queue", str(path))
        assert code == 2, args
        assert f"queue file {path} is damaged (file is not a database); nothing was changed; move it aside" in err
    assert path.read_bytes() == before


def test_damaged_pages_inside_a_queue_are_reported(sqlite_store):
    store = sqlite_store
    fill(store, ["sim://a"], 200)
    store.close()
    with sqlite3.connect(store.path) as db:
        db.execute("PRAGMA wal_checkpoint(TRUNCATE)")
        page = db.execute("PRAGMA page_size").fetchone()[0]
    data = bytearray(store.path.read_bytes())
    for offset in range(2 * page, len(data), page):
        data[offset:offset + 64] = b"\xff" * 64
    store.path.write_bytes(bytes(data))
    with pytest.raises(FoldfabError, match="is damaged .*sqlite3 .* .recover"):
        SqliteQueueStore(store.path).jobs()


def test_tampered_program_is_claimed_for_the_worker_to_fail(store):
    fill(store, ["sim://a", "sim://b"], 1)
    raw_sql(store, "UPDATE snapshots SET program = 'IN;PD0,0;' WHERE id = 1")
    worker = WorkerId.current()
    claim = store.claim(worker, 30)
    assert claim.job.id == 1 and claim.stored is None and "does not match its SHA-256" in claim.damage
    with pytest.raises(FoldfabError, match="job 1: its stored program does not match its SHA-256"):
        claim.snapshot  # noqa: B018 (the worker fails the job with this reason, and says so)
    assert store.finish(1, worker, "failed", claim.damage)
    assert store.claim(worker, 30).snapshot.program.text == snapshot().program.text


# --- the command line ---------------------------------------------------------------------------


def test_cli_add_list_show_and_actions(tmp_path, capsys):
    queue = ["--queue", str(tmp_path / "q.sqlite3")]
    code, out, _ = run_cli(capsys, "queue", "add", str(HEXAGON), "--device", "graphtec-ce6000",
                           "--port", "sim://graphtec-ce6000", "--copies", "2", "--priority", "4", *queue)
    assert code == 0 and "queued jobs 1-2: hexagon relief, Figure 8 (a) on graphtec-ce6000" in out
    code, out, _ = run_cli(capsys, "queue", "list", *queue)
    assert out.splitlines()[1].split()[:5] == ["1", "queued", "4", "0.0%", "graphtec-ce6000"]
    code, out, _ = run_cli(capsys, "queue", "show", "2", *queue)
    assert "copy 2 of 2" in out and "queued (copy 2 of 2)" in out
    assert run_cli(capsys, "queue", "cancel", "2", *queue)[1] == "job 2 cancelled\n"
    assert "queued again" in run_cli(capsys, "queue", "retry", "2", *queue)[1]
    code, _, err = run_cli(capsys, "queue", "continue", "1", *queue)
    assert code == 2 and "job 1 is queued, not waiting at a pause" in err
    import json

    listed = json.loads(run_cli(capsys, "queue", "list", "--state", "queued", "--json", *queue)[1])
    assert [j["id"] for j in listed] == [1, 2]
    assert run_cli(capsys, "queue", "remove", "1", *queue)[1] == "job 1 removed\n"
    assert run_cli(capsys, "queue", "clear", "--done", *queue)[1] == "removed 0 done jobs\n"
    assert json.loads(run_cli(capsys, "queue", "show", "2", "--json", *queue)[1])["job"]["id"] == 2


@pytest.mark.parametrize("args, message", [
    (["show", "99999999999999999999"], "argument ID: expected a job id from 1 to 9223372036854775807, "
                                       "got 99999999999999999999"),
    (["cancel", "9223372036854775808"], "argument ID: expected a job id from 1 to 9223372036854775807"),
    (["retry", "-3"], "argument ID: expected a job id from 1 to"),
    (["remove", "0"], "argument ID: expected a job id from 1 to"),
    (["continue", "1.5"], "argument ID: expected a whole number, got '1.5'"),
    (["add", str(HEXAGON), "--device", "grbl", "--port", "sim://x", "--priority", "99999999999999999999"],
     "argument --priority: expected a priority from -1000 to 1000, got 99999999999999999999"),
    (["add", str(HEXAGON), "--device", "grbl", "--port", "sim://x", "--copies", "99999999999999999999"],
     "argument --copies: expected copies from 1 to 1000"),
    (["add", str(HEXAGON), "--device", "grbl", "--port", ""], "argument --port: expected a serial port or "
                                                              "pyserial URL (such as /dev/ttyUSB0 or sim://grbl), "
                                                              "got an empty one"),
    (["add", str(HEXAGON), "--device", "grbl", "--port", " "], "argument --port: expected a serial port"),
    (["retry", "1", "--port", ""], "argument --port: expected a serial port"),
    (["run", "--port", ""], "argument --port: expected a serial port"),
    (["run", "--lease", "0.5"], "argument --lease: expected at least 5 seconds (5 of the worker's heartbeats, "
                                "one every 1 s), got 0.5"),
    (["run", "--lease", "0"], "argument --lease: expected at least 5 seconds"),
    (["run", "--lease", "-30"], "argument --lease: expected at least 5 seconds"),
    (["run", "--lease", "nan"], "argument --lease: expected at least 5 seconds"),
    (["run", "--lease", "inf"], "argument --lease: expected at least 5 seconds"),
    (["list", "--wait", "nan"], "argument --wait: expected 0 seconds or more, got nan"),
    (["list", "--wait", "-1"], "argument --wait: expected 0 seconds or more, got -1"),
])
def test_out_of_range_arguments_are_refused_before_the_queue_is_touched(tmp_path, capsys, args, message):
    queue = tmp_path / "q.sqlite3"
    with pytest.raises(SystemExit) as stop:
        main(["queue", *args, "--queue", str(queue)])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and "Traceback" not in err
    last = err.splitlines()[-1]
    assert last.startswith(f"foldfab queue {args[0]}: error: {message}")
    assert not queue.exists()


def test_huge_ids_are_no_job_for_the_store(store):
    fill(store, ["sim://a"], 1)
    for call in (store.job, store.snapshot, store.cancel, store.retry, store.continue_job, store.remove):
        with pytest.raises(FoldfabError, match="no job 99999999999999999999 in queue"):
            call(99999999999999999999, *(["test"] if call == store.continue_job else []))
    assert store.events(99999999999999999999) == []


def test_an_empty_port_is_refused_by_the_store(store):
    with pytest.raises(FoldfabError, match="empty port"):
        store.add([NewJob(snapshot(), "")])
    fill(store, ["sim://a"], 1)
    store.cancel(1)
    with pytest.raises(FoldfabError, match="job 1: empty port"):
        store.retry(1, port="")
    assert store.job(1).port == "sim://a"


def test_a_folder_given_as_the_queue_file_is_named_a_folder(tmp_path, capsys):
    for args in (["list"], ["show", "1"], ["run"], ["clear", "--done"],
                 ["add", str(HEXAGON), "--device", "grbl", "--port", "sim://x"]):
        code, _, err = run_cli(capsys, "queue", *args, "--queue", str(tmp_path))
        assert code == 2, args
        assert err == (f"foldfab: error: queue file {tmp_path} is a folder: give the path of a file in it (such "
                       f"as {tmp_path / 'queue.sqlite3'}) with --queue or FOLDFAB_QUEUE\n")
    assert list(tmp_path.iterdir()) == []


def _unwritable_folder_checks(path: Path, new: NewJob) -> None:
    store = SqliteQueueStore(path, wait=0.5)
    try:
        store.add([new])
    except FoldfabError as exc:
        assert str(exc) == (f"queue file {path} cannot be created: its folder {path.parent} is not writable for "
                            "you; nothing was changed; make the folder writable, or choose another queue with "
                            "--queue"), str(exc)
    else:
        raise AssertionError("a queue was created in a folder that is not writable")


def test_a_queue_that_cannot_be_created_blames_its_folder():
    import tempfile

    folder = Path(tempfile.mkdtemp(prefix="foldfab-queue-test-"))
    try:
        os.chmod(folder, 0o555)  # anyone may look in, nobody but root may write
        new = NewJob(snapshot(), "sim://a")
        assert new.snapshot.sha256  # its imports done here: the unprivileged child may not read the modules
        _as_nobody(_unwritable_folder_checks, folder / "queue.sqlite3", new)
        assert list(folder.iterdir()) == []
    finally:
        os.chmod(folder, 0o755)
        shutil.rmtree(folder)


def test_default_queue_location(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("FOLDFAB_QUEUE", raising=False)
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "data"))
    default = tmp_path / "data" / "foldfab" / "queue.sqlite3"
    assert run_cli(capsys, "queue", "list")[1] == f"no jobs in {default}\n"
    assert run_cli(capsys, "queue", "run")[1] == f"nothing to run in {default}\n"
    assert run_cli(capsys, "queue", "clear", "--done")[1] == "removed 0 done jobs\n"
    code, _, err = run_cli(capsys, "queue", "cancel", "3")
    assert code == 2 and "does not exist yet (foldfab queue add creates it)" in err
    assert not (tmp_path / "data").exists()  # only add creates the file
    monkeypatch.setenv("FOLDFAB_QUEUE", str(tmp_path / "env.sqlite3"))
    run_cli(capsys, "queue", "add", str(HEXAGON), "--device", "graphtec-ce6000", "--port", "sim://x")
    assert (tmp_path / "env.sqlite3").exists()


@pytest.mark.parametrize("content, reason", [
    ("[profile]\npoints = [[0, 0], [5, 10]]\n", "[trajectory]: missing table"),
    ("[profile]\npoints = [[0, 0], [5, 10]]\n[trajectory]\ntemplate = \"regular\"\ncorners = 5\nradius = 40\n",
     "even number of corners"),
    ("[profile]\npoints = [[0, 0], [5, 10]]\n[trajectory]\ntemplate = \"regular\"\ncorners = 6\nradius = 40\n"
     "[fabrication]\nscale = 9\n", "largest scale that fits"),
    ("[profile\n", "not valid TOML"),
])
def test_bad_job_files_are_rejected_and_nothing_is_added(tmp_path, capsys, content, reason):
    queue = tmp_path / "q.sqlite3"
    bad = tmp_path / "bad.toml"
    bad.write_text(content)
    code, out, err = run_cli(capsys, "queue", "add", str(HEXAGON), str(bad), "--device", "graphtec-ce6000",
                             "--port", "sim://x", "--queue", str(queue))
    assert code == 2 and out == ""
    assert err.startswith(f"foldfab: error: {bad}") and reason in err and "\n" not in err.rstrip("\n")
    assert SqliteQueueStore(queue).jobs() == []


def test_add_needs_a_known_device_and_a_job_without_port_waits_for_a_plotter_of_its_profile(tmp_path, capsys):
    queue = ["--queue", str(tmp_path / "q.sqlite3")]
    code, _, err = run_cli(capsys, "queue", "add", str(HEXAGON), "--device", "nonesuch", *queue)
    assert code == 2 and "unknown device 'nonesuch'" in err
    assert not (tmp_path / "q.sqlite3").exists()
    profile = tmp_path / "noport.toml"
    profile.write_text("\n".join(line for line in (ROOT / "devices" / "grbl.toml").read_text().splitlines()
                                 if not line.startswith("port")))
    code, out, err = run_cli(capsys, "queue", "add", str(HEXAGON), "--device", str(profile), *queue)
    assert code == 0 and "for any plotter of it (foldfab queue run --device grbl --port PORT)" in out, err
    job = SqliteQueueStore(tmp_path / "q.sqlite3").job(1)
    assert (job.port, job.any_plotter, job.target) == ("", True, "any")
    # a worker without a port of its own has nowhere to run it
    assert run_cli(capsys, "queue", "run", "--dry-run", *queue)[1].startswith("nothing to run")
    out = run_cli(capsys, "queue", "run", "--dry-run", "--device", "grbl", "--port", "sim://grbl?time=instant",
                  *queue)[1]
    assert "job 1: " in out and "1 done (1)" in out


def test_snapshot_does_not_change_when_the_job_and_its_svg_change(tmp_path, capsys):
    folder = tmp_path / "jobs"
    folder.mkdir()
    shutil.copy(ROOT / "jobs" / "vase-profile.svg", folder)
    job = folder / "vase.toml"
    job.write_text((ROOT / "jobs" / "vase-svg.toml").read_text().replace('scale = "fit"', 'sheet = "A3"\nscale = 0.5'))
    queue = tmp_path / "q.sqlite3"
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    os.chdir(elsewhere)  # relative SVG paths resolve against the job file, not the working folder
    try:
        assert run_cli(capsys, "queue", "add", str(job), "--device", "hp7475a", "--port", "sim://hp7475a",
                       "--queue", str(queue))[0] == 0
    finally:
        os.chdir(ROOT)
    store = SqliteQueueStore(queue)
    before = store.snapshot(1)
    job.write_text(job.read_text().replace("corners = 8", "corners = 10").replace("scale = 0.5", "scale = 0.4"))
    (folder / "vase-profile.svg").unlink()
    after = store.snapshot(1)
    assert after == before
    assert "corners = 8" in after.job_text and after.program.text.startswith("IN;")
    assert len(after.program.sections) >= 3


# --- random sequences of operations ------------------------------------------------------------

class QueueMachine(RuleBasedStateMachine):
    """Any sequence of operators' and workers' actions keeps the queue's promises: the states
    follow the transitions of :mod:`foldfab.queue.records`, a plotter runs one job at a time, a plotter
    with an interrupted job runs nothing else, nothing is lost but what is removed."""

    PORTS = ("sim://a", "sim://b")

    def __init__(self):
        super().__init__()
        import tempfile

        self.folder = tempfile.mkdtemp(prefix="foldfab-queue-machine-")
        self.store = SqliteQueueStore(Path(self.folder) / "q.sqlite3")
        self.workers = [WorkerId.current() for _ in range(3)]
        self.states: dict[int, str] = {}
        self.held: dict[int, WorkerId] = {}
        self.ports: dict[int, str] = {}
        self.acked: dict[int, int] = {}
        self.snap = snapshot()

    def teardown(self):
        self.store.close()
        shutil.rmtree(self.folder)

    @rule(port=st.sampled_from(PORTS), copies=st.integers(1, 2), priority=st.integers(0, 2))
    def add(self, port, copies, priority):
        for job_id in self.store.add([NewJob(self.snap, port, priority, copies)]):
            self.states[job_id], self.ports[job_id], self.acked[job_id] = "queued", port, 0

    def _resume(self, job_id: int) -> bool:
        """A half-drawn sheet is on the job's plotter, to be resumed."""
        state = self.states[job_id]
        return state == "interrupted" or (state == "queued" and self.acked[job_id] > 0)

    @rule(worker=st.integers(0, 2))
    def claim(self, worker):
        busy = {self.ports[j] for j, s in self.states.items() if s in ("running", "waiting")}
        blocked = {self.ports[j] for j in self.states if self._resume(j)}
        runnable = [j for j, s in self.states.items() if s in ("queued", "interrupted")
                    and self.ports[j] not in busy and (self._resume(j) or self.ports[j] not in blocked)]
        claim = self.store.claim(self.workers[worker], 3600)
        assert (claim is None) == (not runnable)
        if claim is not None:
            assert claim.job.id in runnable
            assert self._resume(claim.job.id) or not any(self._resume(j) for j in runnable)  # resumes first
            self.states[claim.job.id], self.held[claim.job.id] = "running", self.workers[worker]

    @precondition(lambda self: self.held)
    @rule(data=st.data())
    def progress(self, data):
        job_id = data.draw(st.sampled_from(self._held()))
        self.acked[job_id] += 1
        assert not self.store.heartbeat(job_id, self.held[job_id], 3600, acked_bytes=self.acked[job_id]).lost

    def _held(self):
        return sorted(self.held)

    @precondition(lambda self: self.held)
    @rule(data=st.data(), end=st.sampled_from(["done", "failed", "cancelled", "interrupted"]))
    def finish(self, data, end):
        job_id = data.draw(st.sampled_from(self._held()))
        assert self.store.finish(job_id, self.held.pop(job_id), end, "test")
        self.states[job_id] = end

    @precondition(lambda self: self.held)
    @rule(data=st.data())
    def pause_and_continue(self, data):
        job_id = data.draw(st.sampled_from(self._held()))
        if self.states[job_id] == "running":
            assert self.store.wait_at_pause(job_id, self.held[job_id], "flip").state == "waiting"
            self.states[job_id] = "waiting"
        else:
            self.store.continue_job(job_id, "test")
            self.states[job_id] = "running"

    @precondition(lambda self: self.held)
    @rule(data=st.data())
    def worker_dies(self, data):
        job_id = data.draw(st.sampled_from(self._held()))
        dead = self.held[job_id]
        with sqlite3.connect(self.store.path) as db:
            db.execute("UPDATE jobs SET lease_expires = 0 WHERE worker = ?", (str(dead),))
        for held in [j for j, w in self.held.items() if w == dead]:
            cancel = self.store.job(held).cancel_requested
            self.states[held] = "cancelled" if cancel else "interrupted"
            del self.held[held]
        self.store.log(job_id, "test", "a write expires the dead worker's leases")

    @precondition(lambda self: self.states)
    @rule(data=st.data())
    def cancel(self, data):
        job_id = data.draw(st.sampled_from(sorted(self.states)))
        state = self.states[job_id]
        if state in ("done", "failed", "cancelled") or (state in ("running", "waiting")
                                                         and self.store.job(job_id).cancel_requested):
            if state not in ("running", "waiting"):
                with pytest.raises(FoldfabError):
                    self.store.cancel(job_id)
            return
        job = self.store.cancel(job_id)
        if state in ("queued", "interrupted"):
            self.states[job_id] = "cancelled"
        assert job.state == self.states[job_id]

    @precondition(lambda self: self.states)
    @rule(data=st.data(), restart=st.booleans())
    def retry_or_remove(self, data, restart):
        job_id = data.draw(st.sampled_from(sorted(self.states)))
        state = self.states[job_id]
        if state in ("failed", "cancelled", "interrupted"):
            assert self.store.retry(job_id, restart).state == "queued"
            self.states[job_id] = "queued"
            if restart:
                self.acked[job_id] = 0
        elif state in ("running", "waiting"):
            with pytest.raises(FoldfabError, match="cancel it first"):
                self.store.remove(job_id)
        else:
            self.store.remove(job_id)
            del self.states[job_id], self.acked[job_id]

    @invariant()
    def states_match_and_plotters_run_one_job(self):
        jobs = self.store.jobs()
        assert {j.id: j.state for j in jobs} == self.states
        assert {j.id: j.acked_bytes for j in jobs} == self.acked
        for port in self.PORTS:
            assert len([j for j in jobs if j.port == port and j.state in ("running", "waiting")]) <= 1


QueueMachine.TestCase.settings = settings(max_examples=40, stateful_step_count=25, deadline=None)
test_queue_state_machine = QueueMachine.TestCase


def test_queue_add_on_a_full_disk_says_the_disk_is_full_and_adds_nothing(tmp_path, capsys, monkeypatch):
    """A real SQLITE_FULL: SQLite's own page limit on the connection stands in for the disk.  A
    commit that fails for a full disk is rolled back by SQLite itself; the store must not roll
    back again and report that instead ("cannot rollback - no transaction is active")."""
    queue = tmp_path / "queue.sqlite3"
    args = ["queue", "add", "--queue", str(queue), "--device", "hp7475a", "--port", "sim://hp7475a", str(HEXAGON)]
    assert run_cli(capsys, *args)[0] == 0
    connect = SqliteQueueStore._connect

    def full(self):
        fresh = self._db is None
        db = connect(self)
        if fresh:  # no page more than the file has now
            db.execute(f"PRAGMA max_page_count = {db.execute('PRAGMA page_count').fetchone()[0]}")
        return db
    monkeypatch.setattr(SqliteQueueStore, "_connect", full)
    code, out, err = run_cli(capsys, *args)
    assert code == 2 and out == "" and len(err.splitlines()) == 1
    assert f"queue file {queue}: the disk is full" in err and "nothing was changed" in err
    assert "free space on the disk" in err and "rollback" not in err
    monkeypatch.undo()
    assert len(SqliteQueueStore(queue).jobs()) == 1
