"""Plotters registered by name and host, their state, and jobs targeted at a plotter, at any plotter
of a profile, or at a port; on both stores (SQLite and PostgreSQL)."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from foldfab.cli import main
from foldfab.devices import load_device
from foldfab.errors import FoldfabError
from foldfab.programs.program import Program
from foldfab.queue.location import open_queue
from foldfab.queue.limits import MAX_PLOTTER_NAME
from foldfab.queue.records import NewJob, WorkerId
from foldfab.queue.schema import VERSION, migrations
from foldfab.queue.snapshot import make_snapshot, program_meta
from foldfab.queue.worker import Worker, WorkerOptions
from helpers import HEXAGON
from helpers.cli import run as run_cli
from helpers.processes import wait_for
from helpers.queues import raw_sql

TWO_STROKES = "IN;SP1;PU0,0;PD400,0;PU0,100;PD400,100;SP0;"


def snapshot(device: str = "graphtec-ce6000", text: str = TWO_STROKES):
    profile = load_device(device)
    return make_snapshot(Path("job.toml"), "[design]\n", f"a job for {device}", profile,
                         Program(text, "hpgl", profile.name, (), ()))


def where(store) -> str:
    return getattr(store, "url", None) or str(store.path)


def elsewhere(token: str) -> WorkerId:
    """A worker on another host (its process cannot be checked from here: only its lease counts)."""
    return WorkerId("another-host", 4242, token)



def states(store) -> dict[str, tuple]:
    return {p.name: (p.state, p.job.id if p.job else None) for p in store.plotters()}


# --- registration and state -------------------------------------------------------------------


class Terminal:
    """A worker UI without a person: shows nothing; an answer is waited for as a terminal would."""

    def __init__(self):
        self.never = threading.Event()

    def job_started(self, job, note): pass
    def progress(self, event): pass
    def paused(self, job, message): pass
    def answer(self, timeout): return self.never.wait(timeout) and None
    def job_ended(self, job, state, message): pass


class SteppedPlotter:
    """Draws the first stroke, waits for ``go``, pauses for the flip (the operator answers with
    foldfab queue continue), draws the rest."""

    def __init__(self):
        self.drew_one, self.go = threading.Event(), threading.Event()

    def __call__(self, program, device, port, *, events, cancel, operator):
        from foldfab.plotting.progress import JobProgress

        progress = JobProgress(program, device)
        first = progress.strokes[0].end
        events(progress.event("start", 0, 0, 0.0))
        events(progress.event("progress", first, first, 0.1))
        self.drew_one.set()
        assert self.go.wait(60)
        assert operator("flip the sheet")
        events(progress.event("done", len(program.text), len(program.text), 1.0))


def test_a_worker_registers_its_plotter_shows_what_it_draws_and_signs_off(store):
    store.add([NewJob(snapshot(), "", plotter=None, any_plotter=True)])
    plotter = SteppedPlotter()
    options = WorkerOptions(device="graphtec-ce6000", port="sim://cutter", name="pi-a", mode="once",
                            heartbeat=0.1, lease=30)
    worker = Worker(store, Terminal(), options, runner=plotter, locate=False)
    ended = []
    thread = threading.Thread(target=lambda: ended.append(worker.run()), daemon=True)
    thread.start()
    assert plotter.drew_one.wait(60)
    [pi_a] = store.plotters()
    assert (pi_a.name, pi_a.host, pi_a.port, pi_a.device, pi_a.worker) == (
        "pi-a", worker.id.host, "sim://cutter", "graphtec-ce6000", str(worker.id))
    assert (pi_a.state, pi_a.job.id, round(pi_a.job.percent), pi_a.offline_since) == ("drawing", 1, 50, None)
    assert store.job(1).port == "sim://cutter" and store.job(1).plotter == "pi-a"  # claimed here: now its
    plotter.go.set()
    wait_for(lambda: states(store)["pi-a"] == ("paused", 1))
    store.continue_job(1, "the test")
    thread.join(60)
    assert ended and ended[0].ended == {"done": [1]}
    [pi_a] = store.plotters()
    assert pi_a.state == "offline" and pi_a.job is None and pi_a.offline_since == pi_a.stopped >= pi_a.seen


def test_an_idle_plotter_heartbeats_and_a_silent_one_is_offline_since_its_last_heartbeat(store):
    fast, slow = elsewhere("fast"), elsewhere("slow")
    store.register_plotter("fast", "sim://a", "hp7475a", fast, 30)
    store.register_plotter("slow", "sim://b", "hp7475a", slow, 0.3)
    assert states(store) == {"fast": ("idle", None), "slow": ("idle", None)}
    before = {p.name: p.seen for p in store.plotters()}
    assert store.plotter_alive("slow", slow) and not store.plotter_alive("slow", fast)
    beat = {p.name: p.seen for p in store.plotters()}["slow"]
    assert beat >= before["slow"]
    wait_for(lambda: states(store)["slow"] == ("offline", None))  # no heartbeat for longer than its lease
    listed = {p.name: p for p in store.plotters()}
    assert listed["slow"].offline_since == listed["slow"].seen == beat and listed["slow"].stopped is None
    assert listed["fast"].state == "idle"


def test_a_job_heartbeat_and_an_idle_worker_keep_the_plotter_online(store):
    worker = elsewhere("w")
    store.register_plotter("pi-a", "sim://a", None, worker, 30)
    store.add([NewJob(snapshot(), "sim://a")])
    store.claim(worker, 30, port="sim://a", plotter="pi-a")
    before = store.plotters()[0].seen
    wait_for(lambda: time.time() > before)
    store.heartbeat(1, worker, 30, acked_bytes=3)
    assert store.plotters()[0].seen > before
    store.finish(1, worker, "done", "drawn")
    follower = Worker(store, Terminal(), WorkerOptions(port="sim://b", name="pi-b", mode="follow", heartbeat=0.1,
                                                       lease=30, poll=0.2))
    thread = threading.Thread(target=follower.run, daemon=True)
    thread.start()
    wait_for(lambda: states(store).get("pi-b") == ("idle", None))
    registered = {p.name: p for p in store.plotters()}["pi-b"].seen
    wait_for(lambda: {p.name: p for p in store.plotters()}["pi-b"].seen > registered)  # its idle heartbeat
    follower.stop()
    thread.join(60)
    assert states(store)["pi-b"] == ("offline", None)


def test_a_plotter_whose_worker_process_on_this_host_is_gone_is_offline_at_once(store):
    process = subprocess.Popen([sys.executable, "-c", "pass"])
    process.wait()
    ghost = WorkerId(WorkerId.current().host, process.pid, "ghost")
    store.register_plotter("ghost", "sim://a", None, ghost, 3600)
    [plotter] = store.plotters()
    assert plotter.state == "offline" and plotter.offline_since == plotter.seen
    store.register_plotter("ghost", "sim://a", None, WorkerId.current(), 30)  # a new worker takes it over
    assert states(store) == {"ghost": ("idle", None)}


def test_a_name_is_held_by_one_online_worker(store):
    first, second = elsewhere("first"), elsewhere("second")
    store.register_plotter("pi-a", "sim://a", "hp7475a", first, 30)
    with pytest.raises(FoldfabError, match="plotter pi-a is registered by worker another-host/4242/first on "
                                           "another-host, which runs .*give this plotter another name with --name"):
        store.register_plotter("pi-a", "sim://b", "hp7475a", second, 30)
    store.register_plotter("pi-a", "sim://a", "hp7475a", first, 30)  # its own worker again: fine
    store.unregister_plotter("pi-a", second)  # not its plotter: nothing happens
    assert states(store) == {"pi-a": ("idle", None)}
    store.unregister_plotter("pi-a", first)
    store.register_plotter("pi-a", "sim://b", "hp7475a", second, 30)  # offline now: taken over
    [plotter] = store.plotters()
    assert (plotter.port, plotter.worker, plotter.state) == ("sim://b", str(second), "idle")
    assert not store.plotter_alive("pi-a", first)  # the old worker learns it is no longer its


# --- targeting --------------------------------------------------------------------------------


def test_claims_take_jobs_for_their_plotter_and_profile_only(store):
    pi_a, pi_b, pi_c, pi_d = elsewhere("a"), elsewhere("b"), elsewhere("c"), elsewhere("d")
    store.register_plotter("pi-a", "sim://a", "graphtec-ce6000", pi_a, 30)
    store.register_plotter("pi-b", "sim://b", "graphtec-ce6000", pi_b, 30)
    store.register_plotter("pi-c", "sim://c", "hp7475a", pi_c, 30)
    store.register_plotter("pi-d", "sim://d", None, pi_d, 30)  # its worker was given no --device
    ids = store.add([NewJob(snapshot(), "", plotter="pi-b"),                          # 1: only pi-b
                     NewJob(snapshot("hp7475a"), "/dev/ttyUSB0", any_plotter=True),  # 2: any hp7475a
                     NewJob(snapshot(), "/dev/ttyUSB0", any_plotter=True),           # 3: any ce6000
                     NewJob(snapshot(), "sim://a"),                                  # 4: the plotter at sim://a
                     NewJob(snapshot(), "", -1, any_plotter=True)])                  # 5: any ce6000, last
    assert ids == [1, 2, 3, 4, 5]
    assert store.job(1).port == "sim://b" and store.job(1).target == "pi-b"
    mine = {"pi-a": ("graphtec-ce6000", "sim://a"), "pi-b": ("graphtec-ce6000", "sim://b"),
            "pi-c": ("hp7475a", "sim://c"), "pi-d": (None, "sim://d")}

    def runnable():
        return {name: [j.id for j in store.runnable(device, port, plotter=name)] for name, (device, port) in mine.items()}
    assert runnable() == {"pi-a": [3, 4, 5], "pi-b": [1, 3, 5], "pi-c": [2], "pi-d": []}
    assert [j.id for j in store.runnable()] == [2, 3, 4]  # a worker without a port: the jobs that name one
    claim = store.claim(pi_a, 30, *mine["pi-a"], plotter="pi-a")
    assert (claim.job.id, claim.job.port, claim.job.plotter, claim.job.any_plotter) == (3, "sim://a", "pi-a", False)
    assert "on plotter pi-a at sim://a" in store.events(3)[-1].message
    assert runnable()["pi-a"] == []  # pi-a is busy: not even a job for any plotter of its profile
    assert store.claim(pi_b, 30, *mine["pi-b"], plotter="pi-b").job.id == 1
    assert store.claim(pi_b, 30, *mine["pi-b"], plotter="pi-b") is None
    store.heartbeat(3, pi_a, 30, acked_bytes=12)
    store.finish(3, pi_a, "interrupted", "the host lost power")
    store.finish(1, pi_b, "done", "drawn")
    # the half-drawn sheet is on pi-a: no other plotter of its profile takes it, and pi-a takes it first
    assert store.claim(pi_b, 30, *mine["pi-b"], plotter="pi-b").job.id == 5
    assert store.claim(pi_a, 30, *mine["pi-a"], plotter="pi-a").job.id == 3
    assert store.claim(pi_c, 30, *mine["pi-c"], plotter="pi-c").job.id == 2
    assert store.claim(WorkerId.current(), 30) is None  # job 4: sim://a is busy


def _claim_on(location: str, port: str, held: list, errors: list, lock: threading.Lock) -> None:
    """A worker of a plotter at ``port``: claim, hold, finish, until nothing is left; a second
    job held at the port at once is an error."""
    store = open_queue(location, wait=30)
    worker = WorkerId.current()
    try:
        while claim := store.claim(worker, 30, "graphtec-ce6000", port):
            with lock:
                if held:
                    errors.append(f"jobs {held[0]} and {claim.job.id} at {port} at once")
                held.append(claim.job.id)
            store.log(claim.job.id, "test", "drawing")
            with lock:
                held.remove(claim.job.id)
            store.finish(claim.job.id, worker, "done", "drawn")
    finally:
        store.close()


def test_racing_workers_of_one_plotter_never_hold_two_jobs_for_any_plotter_of_its_profile(store):
    """The jobs for any plotter name different ports (their profiles' defaults) until claimed: the
    plotter a claim takes is the worker's, whatever the job's port says."""
    store.add([NewJob(snapshot(), f"/dev/ttyUSB{i % 5}" if i % 5 else "", any_plotter=True) for i in range(40)])
    held, errors, lock = [], [], threading.Lock()
    threads = [threading.Thread(target=_claim_on, args=(where(store), "sim://shared", held, errors, lock))
               for _ in range(6)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(300)
    assert errors == []
    assert [j.state for j in store.jobs()] == ["done"] * 40
    assert {j.port for j in store.jobs()} == {"sim://shared"}


def test_a_job_for_an_unknown_plotter_or_one_of_another_profile_is_refused(store, capsys):
    store.register_plotter("pi-c", "sim://c", "hp7475a", elsewhere("c"), 30)
    with pytest.raises(FoldfabError, match="no plotter 'ghost' in queue .*foldfab queue plotters lists them"):
        store.add([NewJob(snapshot(), "", plotter="ghost")])
    with pytest.raises(FoldfabError, match="plotter pi-c is a hp7475a, but a job for graphtec-ce6000 is for "
                                           "graphtec-ce6000: choose a plotter of graphtec-ce6000"):
        store.add([NewJob(snapshot("hp7475a"), "sim://z"), NewJob(snapshot(), "", plotter="pi-c")])
    assert store.jobs() == []  # all or nothing
    code, out, err = run_cli(capsys, "queue", "add", str(HEXAGON), "--device", "grbl", "--plotter", "ghost",
                             "--queue", where(store))
    assert (code, out) == (2, "") and len(err.splitlines()) == 1 and "no plotter 'ghost' in queue" in err
    assert store.jobs() == []


def test_queue_move_to_a_plotter_of_the_same_profile_only(store, capsys):
    pi_a, pi_b = elsewhere("a"), elsewhere("b")
    store.register_plotter("pi-a", "sim://a", "graphtec-ce6000", pi_a, 30)
    store.register_plotter("pi-b", "sim://b", "graphtec-ce6000", pi_b, 30)
    store.register_plotter("pi-c", "sim://c", "hp7475a", elsewhere("c"), 30)
    store.add([NewJob(snapshot(), "", plotter="pi-a")])
    store.claim(pi_a, 30, "graphtec-ce6000", "sim://a", plotter="pi-a")
    store.heartbeat(1, pi_a, 30, acked_bytes=12)
    store.finish(1, pi_a, "interrupted", "pi-a broke down")
    queue = ["--queue", where(store)]
    for target, message in (("pi-c", "plotter pi-c is a hp7475a, but job 1 is for graphtec-ce6000: choose a plotter "
                                      "of graphtec-ce6000"), ("ghost", "no plotter 'ghost' in queue")):
        code, out, err = run_cli(capsys, "queue", "move", "1", "--plotter", target, *queue)
        assert (code, out) == (2, "") and len(err.splitlines()) == 1 and message in err, err
    assert (store.job(1).state, store.job(1).plotter) == ("interrupted", "pi-a")
    code, out, _ = run_cli(capsys, "queue", "move", "1", "--plotter", "pi-b", *queue)
    assert code == 0 and "resumes at byte 12" in out and "before any other job at pi-b" in out
    assert (store.job(1).port, store.job(1).plotter) == ("sim://b", "pi-b")
    assert "on plotter pi-b at sim://b (was pi-a at sim://a)" in store.events(1)[-1].message
    store.cancel(1)
    assert run_cli(capsys, "queue", "move", "1", "--port", "sim://z", *queue)[0] == 0  # a port: no plotter by name
    assert (store.job(1).port, store.job(1).plotter) == ("sim://z", None)
    store.cancel(1)
    run_cli(capsys, "queue", "move", "1", "--plotter", "pi-b", *queue)
    assert store.claim(pi_a, 30, "graphtec-ce6000", "sim://a", plotter="pi-a") is None
    assert store.claim(pi_b, 30, "graphtec-ce6000", "sim://b", plotter="pi-b").job.acked_bytes == 12


# --- hostile input ----------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["pi\x1b[2J", "a\nb", "tab\there", " padded", "", "x" * 10_000,
                                  "x" * (MAX_PLOTTER_NAME + 1)])
def test_a_plotter_name_with_control_characters_or_too_long_is_refused(store, capsys, name):
    with pytest.raises(FoldfabError, match="expected 1 to 200 printable characters") as refused:
        store.register_plotter(name, "sim://a", None, elsewhere("w"), 30)
    assert len(str(refused.value)) < 400 and "\n" not in str(refused.value)
    for args in (["run", "--port", "sim://a", "--name", name], ["move", "1", "--plotter", name],
                 ["add", str(HEXAGON), "--device", "grbl", "--plotter", name]):
        with pytest.raises(SystemExit) as stop:
            main(["queue", *args, "--queue", where(store)])
        err = capsys.readouterr().err
        assert stop.value.code == 2 and "expected 1 to 200 printable characters" in err.splitlines()[-1]
        assert len(err.splitlines()[-1]) < 500
    assert store.plotters() == []


def test_queue_plotters_escapes_what_a_hostile_row_holds(store, capsys):
    store.register_plotter("pi-a", "sim://a", "hp7475a", elsewhere("a"), 30)
    raw_sql(store, "UPDATE plotters SET name = ?, host = ?", ("evil\x1b]0;owned\x07", "host\x1b[2J"))
    code, out, _ = run_cli(capsys, "queue", "plotters", "--queue", where(store))
    assert code == 0 and "\x1b" not in out and "\x07" not in out
    assert "evil\\x1b]0;owned\\x07" in out and "host\\x1b[2J" in out
    listed = json.loads(run_cli(capsys, "queue", "plotters", "--json", "--queue", where(store))[1])
    assert listed[0]["name"] == "evil\x1b]0;owned\x07"  # JSON escapes it itself


def test_a_damaged_registration_is_reported_and_mended_by_registering_again(sqlite_store, capsys):
    store = sqlite_store
    store.register_plotter("pi-a", "sim://a", "hp7475a", elsewhere("a"), 30)
    raw_sql(store, "UPDATE plotters SET seen = 'yesterday', lease = 1e999")
    code, out, err = run_cli(capsys, "queue", "plotters", "--queue", where(store))
    assert code == 2 and out == "" and len(err.splitlines()) == 1
    assert "the registration of plotter 'pi-a' is damaged" in err and "Traceback" not in err
    store.register_plotter("pi-a", "sim://a", "hp7475a", elsewhere("b"), 30)
    assert states(store) == {"pi-a": ("idle", None)}


# --- the schema and the command line ----------------------------------------------------------


def test_a_queue_of_the_previous_schema_version_migrates_forward(store):
    """A queue made by the foldfab before plotters (schema 3), with an interrupted job, opens with
    this one: its jobs keep their port, have no plotter, and resume."""
    dialect = "postgres" if hasattr(store, "url") else "sqlite"
    for step in migrations(dialect)[:3]:
        for statement in step:
            raw_sql(store, statement)
    if dialect == "sqlite":
        raw_sql(store, "PRAGMA user_version = 3")
    else:
        raw_sql(store, "CREATE TABLE foldfab_schema (version INTEGER NOT NULL)")
        raw_sql(store, "INSERT INTO foldfab_schema (version) VALUES (3)")
    snap = snapshot()
    raw_sql(store, "INSERT INTO snapshots (name, job_path, device, program_bytes, program_sha256, program_meta, "
            "job_text, device_text, program) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
            (snap.name, snap.job_path, snap.device, len(snap.program.text), snap.sha256, program_meta(snap.program),
             snap.job_text, snap.device_text, snap.program.text))
    raw_sql(store, "INSERT INTO jobs (snapshot_id, port, state, created, updated, acked_bytes) "
            "VALUES (1, 'sim://a', 'interrupted', 0, 0, 12)")
    job = store.job(1)
    assert (job.state, job.port, job.plotter, job.any_plotter, job.acked_bytes) == (
        "interrupted", "sim://a", None, False, 12)
    assert store.plotters() == []
    if dialect == "sqlite":
        assert raw_sql(store, "PRAGMA user_version") == [(VERSION,)]
    else:
        assert raw_sql(store, "SELECT version FROM foldfab_schema") == [(VERSION,)]
    worker = elsewhere("a")
    store.register_plotter("pi-a", "sim://a", "graphtec-ce6000", worker, 30)
    claim = store.claim(worker, 30, "graphtec-ce6000", "sim://a", plotter="pi-a")
    assert (claim.job.id, claim.job.acked_bytes, claim.job.plotter) == (1, 12, "pi-a")


def test_cli_queue_plotters_lists_name_host_profile_port_and_state(tmp_path, capsys):
    queue = ["--queue", str(tmp_path / "q.sqlite3")]
    assert run_cli(capsys, "queue", "plotters", *queue)[1].startswith("no plotters registered in ")
    store = open_queue(str(tmp_path / "q.sqlite3"))
    busy, idle, gone = elsewhere("busy"), elsewhere("idle"), elsewhere("gone")
    store.register_plotter("pi-a", "sim://a", "graphtec-ce6000", busy, 30)
    store.register_plotter("pi-b", "/dev/serial/by-id/usb-FTDI", "hp7475a", idle, 30)
    store.register_plotter("pi-c", "sim://c", None, gone, 30)
    store.unregister_plotter("pi-c", gone)
    store.add([NewJob(snapshot(), "", plotter="pi-a")])
    store.claim(busy, 30, "graphtec-ce6000", "sim://a", plotter="pi-a")
    store.heartbeat(1, busy, 30, acked_bytes=20, drawn=(10.0, 40.0))
    code, out, _ = run_cli(capsys, "queue", "plotters", *queue)
    lines = out.splitlines()
    assert code == 0 and lines[0].split() == ["NAME", "HOST", "PROFILE", "PORT", "STATE"]
    assert lines[1].split()[:6] == ["pi-a", "another-host", "graphtec-ce6000", "sim://a", "drawing", "job"]
    assert lines[1].endswith("drawing job 1 at 25%")
    assert lines[2].split() == ["pi-b", "another-host", "hp7475a", "/dev/serial/by-id/usb-FTDI", "idle"]
    stopped = store.plotters()[2].stopped
    assert lines[3].split()[:4] == ["pi-c", "another-host", "-", "sim://c"]
    assert lines[3].endswith(f"offline since {time.strftime('%Y-%m-%d %H:%M:%S', time.localtime(stopped))} "
                             "(its worker stopped)")
    store.wait_at_pause(1, busy, "flip the sheet")
    line = run_cli(capsys, "queue", "plotters", *queue)[1].splitlines()[1]
    assert "paused in job 1 at 25%: waits for the operator" in line and "foldfab queue continue 1" in line
    listed = json.loads(run_cli(capsys, "queue", "plotters", "--json", *queue)[1])
    assert [(p["name"], p["state"], p["job"], p["percent"]) for p in listed] == [
        ("pi-a", "paused", 1, 25.0), ("pi-b", "idle", None, None), ("pi-c", "offline", None, None)]
    assert listed[2]["offline_since"] == stopped and listed[0]["host"] == "another-host"
    listing = run_cli(capsys, "queue", "list", *queue)[1].splitlines()
    assert "PLOTTER/PORT" in listing[0] and listing[1].split()[5] == "pi-a"
    store.close()


def test_cli_queue_run_registers_its_plotter_by_name(tmp_path, capsys):
    queue = ["--queue", str(tmp_path / "q.sqlite3")]
    code, _, err = run_cli(capsys, "queue", "run", "--name", "pi-a", *queue)
    assert code == 2 and "plotter pi-a: a named plotter needs its port: give --port PORT" in err
    assert run_cli(capsys, "queue", "add", str(HEXAGON), "--device", "grbl", *queue)[0] == 0
    code, out, err = run_cli(capsys, "queue", "run", "--device", "grbl", "--port", "sim://grbl?time=instant",
                             "--name", "pi-a", *queue)
    assert code == 0 and "1 done (1)" in out, err
    [plotter] = open_queue(str(tmp_path / "q.sqlite3")).plotters()
    assert (plotter.name, plotter.device, plotter.port, plotter.state) == ("pi-a", "grbl", "sim://grbl?time=instant",
                                                                           "offline")
    code, out, _ = run_cli(capsys, "queue", "run", "--port", "sim://grbl?time=instant", *queue)
    names = {p.name for p in open_queue(str(tmp_path / "q.sqlite3")).plotters()}
    assert code == 0 and names == {"pi-a", f"{WorkerId.current().host}:sim://grbl?time=instant"}  # host:port
