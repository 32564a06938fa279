"""The queue worker: order, progress, pauses, cancel, faults, resume after a dead worker."""

from __future__ import annotations

import bisect
import json
import re
import signal
import sqlite3
import subprocess
import sys
import threading
import time
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from foldfab.cli import main
from foldfab.design import load_design
from foldfab.devices import load_device
from foldfab.fabricate import fabricate
from foldfab.fabrication.spec import parse_fabrication
from foldfab.programs.interpret import interpret
from foldfab.plotting.progress import JobProgress
from foldfab.queue.records import NewJob
from foldfab.queue.snapshot import make_snapshot
from foldfab.queue.sqlite import SqliteQueueStore
from foldfab.plotting.engines.base import StreamStopped
from foldfab.queue.worker import PortUnavailable, Worker, WorkerOptions, rehearse, start_point
from helpers import HEXAGON, ROOT
from helpers.processes import wait_for, wait_for_handler



def build(device_name: str, strategy: str = "force"):
    """A snapshot of the Figure 8 (a) hexagon for a device."""
    device = load_device(device_name)
    design = load_design(HEXAGON)
    spec = parse_fabrication(dict(design.job.fabrication, strategy=strategy), str(HEXAGON))
    return make_snapshot(HEXAGON, design.job.text, design.job.name, device, fabricate(design, device, spec).program)


@pytest.fixture(scope="module")
def snapshots():
    built = {(name, strategy): build(name, strategy)
             for name in ("graphtec-ce6000", "grbl", "hp7475a") for strategy in ("force", "two-sided")}
    return built | {("hp7475a", "perforate"): build("hp7475a", "perforate")}


@pytest.fixture()
def store(tmp_path):
    store = SqliteQueueStore(tmp_path / "queue.sqlite3", wait=5.0)
    yield store
    store.close()


def points(stroke) -> tuple:
    return tuple(tuple(round(c, 6) for c in p) for p in stroke.points)


class Console:
    """A worker UI for tests: records what it is shown; answers pauses from a script
    (None: no terminal, like a worker started by a service manager)."""

    def __init__(self, answers: list[str] | None = None):
        self.answers = answers
        self.lines: list[str] = []
        self.events = 0
        self.asked = 0

    def job_started(self, job, note):
        self.lines.append(f"start {job.id} {note}")

    def progress(self, event):
        self.events += 1

    def paused(self, job, message):
        self.lines.append(f"pause {job.id} {message}")

    def answer(self, timeout):
        self.asked += 1
        if self.answers:
            return self.answers.pop(0)
        time.sleep(min(timeout, 0.05))
        return None

    def job_ended(self, job, state, message):
        self.lines.append(f"end {job.id} {state} {message}")


class FakePlotter:
    """A runner that 'draws' stroke by stroke (recording each stroke's points per port), reports
    progress, asks at pauses, honours the cancel event, and fails where told."""

    def __init__(self, delay: float = 0.0, fail_at: dict[int, tuple[int, bool]] | None = None):
        self.delay = delay
        self.fail_at = dict(fail_at or {})  # job's nth run -> (stroke index, tool lifted)
        self.drawn: dict[str, list[tuple]] = {}
        self.runs = 0
        self.lock = threading.Lock()

    def __call__(self, program, device, port, *, events, cancel, operator):
        with self.lock:
            self.runs += 1
            run = self.runs
        progress = JobProgress(program, device)
        strokes = progress.strokes
        pauses = list(program.pauses)
        acked, asked, started = 0, 0, time.monotonic()

        def stop(message, cancelled, lifted):
            raise StreamStopped(message, acknowledged=acked, pauses_done=asked, cancelled=cancelled, lifted=lifted)

        events(progress.event("start", 0, 0, 0.0))
        for index, stroke in enumerate(strokes):
            while asked < len(pauses) and pauses[asked].offset <= stroke.offset:
                acked = max(acked, pauses[asked].offset)
                events(progress.event("pause", acked, acked, time.monotonic() - started))
                if not operator(pauses[asked].message):
                    stop("stopped at a pause", True, True)
                asked += 1
            if cancel.is_set():
                stop("stopped on request", True, True)
            if run in self.fail_at and self.fail_at[run][0] == index:
                stop("serial link failed: cable pulled" if not self.fail_at[run][1] else
                     "plotter reports HP-GL error 3 (out-of-range parameters)", False, self.fail_at[run][1])
            time.sleep(self.delay)
            with self.lock:
                self.drawn.setdefault(port, []).append(points(stroke))
            acked = stroke.end
            events(progress.event("progress", acked, acked, time.monotonic() - started))
        events(progress.event("done", len(program.text), len(program.text), time.monotonic() - started))


def original_strokes(snapshot) -> list[tuple]:
    return [points(s) for s in interpret(snapshot.program, load_device(snapshot.device)).strokes]


def in_thread(worker: Worker) -> threading.Thread:
    thread = threading.Thread(target=worker.run, daemon=True)
    thread.start()
    return thread



# --- resume arithmetic -------------------------------------------------------------------------


@pytest.mark.parametrize("device", ["graphtec-ce6000", "grbl"])
def test_start_point_maps_resumed_offsets_and_pauses_back(snapshots, device):
    snap = snapshots[(device, "two-sided")]
    profile = load_device(device)
    strokes = interpret(snap.program, profile).strokes
    flip = snap.program.pauses[0].offset
    for k in range(1, len(strokes)):
        acked = strokes[k - 1].end
        done_before = sum(p.offset < acked for p in snap.program.pauses)
        start = start_point(snap.program, profile, acked, done_before)
        again = interpret(start.program, profile).strokes
        assert [points(s) for s in again] == [points(s) for s in strokes[k:]]  # nothing lost, nothing twice
        assert [start.original(s.end) for s in again] == [s.end for s in strokes[k:]]
        assert start.stroke == k and start.note.startswith(f"resumed at stroke {k + 1} of {len(strokes)}")
        assert len(start.program.pauses) == len(start.confirmed)
        assert start.confirmed == ((1,) if acked < flip else ())  # answering the flip confirms pause 1
    last = start_point(snap.program, profile, strokes[-1].end, 1)  # every stroke drawn, the closing not acked
    assert interpret(last.program, profile).strokes == [] and last.note.startswith(f"all {len(strokes)} strokes")
    assert last.program.text.endswith(snap.program.text[strokes[-1].end:])  # the program's own closing
    assert last.original(len(last.program.text)) == len(snap.program.text)


# --- running jobs --------------------------------------------------------------------------------


def test_worker_runs_jobs_by_priority_then_arrival_and_saves_progress(store, snapshots):
    snap = snapshots[("graphtec-ce6000", "force")]
    store.add([NewJob(snap, "sim://a", 0, 2), NewJob(snap, "sim://a", 5)])
    plotter, console = FakePlotter(), Console()
    summary = Worker(store, console, WorkerOptions(), runner=plotter).run()
    assert summary.ended == {"done": [3, 1, 2]}
    assert [line.split()[1] for line in console.lines if line.startswith("start")] == ["3", "1", "2"]
    assert plotter.drawn["sim://a"] == original_strokes(snap) * 3
    for job in store.jobs():
        assert (job.state, job.acked_bytes, job.attempts) == ("done", job.program_bytes, 1)
        assert job.progress.startswith(f"stroke {len(original_strokes(snap))} of {len(original_strokes(snap))}")
        assert [e.kind for e in store.events(job.id)] == ["queued", "started", "done"]
    assert console.events > 3


def test_once_and_filters(store, snapshots):
    store.add([NewJob(snapshots[("graphtec-ce6000", "force")], "sim://a"),
               NewJob(snapshots[("grbl", "force")], "sim://b", 0, 2)])
    plotter = FakePlotter()
    assert Worker(store, Console(), WorkerOptions(device="grbl", mode="once"), runner=plotter).run().ended == \
        {"done": [2]}
    assert Worker(store, Console(), WorkerOptions(port="sim://a"), runner=plotter).run().ended == {"done": [1]}
    assert [j.state for j in store.jobs()] == ["done", "done", "queued"]


def test_follow_waits_for_new_jobs(store, snapshots):
    plotter = FakePlotter()
    worker = Worker(store, Console(), WorkerOptions(mode="follow", poll=0.05), runner=plotter)
    looked, claim = [], store.claim
    store.claim = lambda *args, **kw: looked.append(1) or claim(*args, **kw)
    thread = in_thread(worker)
    wait_for(lambda: len(looked) >= 2)  # it found nothing and looked again: it follows
    store.add([NewJob(snapshots[("grbl", "force")], "sim://a")])
    wait_for(lambda: store.job(1).state == "done")
    worker.stop()
    thread.join(5)
    assert not thread.is_alive()


def test_two_sided_job_waits_until_queue_continue(store, snapshots, capsys):
    snap = snapshots[("graphtec-ce6000", "two-sided")]
    store.add([NewJob(snap, "sim://a")])
    console = Console()  # no terminal
    thread = in_thread(Worker(store, console, WorkerOptions(heartbeat=0.1, poll=0.1), runner=FakePlotter()))
    wait_for(lambda: store.job(1).state == "waiting")
    job = store.job(1)
    assert job.acked_bytes == snap.program.pauses[0].offset
    assert "Flip the sheet" in [e for e in store.events(1) if e.kind == "pause"][0].message
    # list shows the share done as foldfab plot does: of the drawn length (the valleys), not of the bytes
    at_pause = JobProgress(snap.program, load_device(snap.device)).event("pause", job.acked_bytes, 0, 0.0)
    valleys = sum(s.length for s in interpret(snap.program, load_device(snap.device)).strokes if s.layer == "valley")
    assert (job.drawn_mm, job.drawn_total_mm) == pytest.approx((valleys, at_pause.drawn_total))
    assert job.percent == pytest.approx(100 * at_pause.fraction)
    assert abs(job.percent - 100 * job.acked_bytes / job.program_bytes) > 1
    assert main(["queue", "list", "--queue", str(store.path)]) == 0
    assert f"{job.percent:5.1f}%" in capsys.readouterr().out
    asked = console.asked
    wait_for(lambda: console.asked >= asked + 3)  # the worker looked for an answer three more times
    assert store.job(1).state == "waiting"  # still: nobody answered
    assert main(["queue", "continue", "1", "--queue", str(store.path)]) == 0
    assert "job 1 continues on worker" in capsys.readouterr().out
    thread.join(20)
    job = store.job(1)
    assert (job.state, job.pauses_done) == ("done", 1)
    kinds = [e.kind for e in store.events(1)]
    assert kinds == ["queued", "started", "pause", "continued", "done"]


@pytest.mark.parametrize("answer, state", [("continue", "done"), ("cancel", "cancelled")])
def test_pause_answered_on_the_workers_terminal(store, snapshots, answer, state):
    store.add([NewJob(snapshots[("grbl", "two-sided")], "sim://a")])
    console = Console(answers=[answer])
    summary = Worker(store, console, WorkerOptions(), runner=FakePlotter()).run()
    assert summary.ended == {state: [1]}
    assert any(line.startswith("pause 1 Valleys are scored. Flip the sheet") for line in console.lines)
    if state == "cancelled":
        assert "cancelled (the operator at the worker's terminal)" in store.job(1).reason


def test_cancel_of_a_running_job_stops_the_plotter(store, snapshots):
    snap = snapshots[("graphtec-ce6000", "force")]
    store.add([NewJob(snap, "sim://a"), NewJob(snap, "sim://a")])
    plotter = FakePlotter(delay=0.05)
    thread = in_thread(Worker(store, Console(), WorkerOptions(heartbeat=0.05), runner=plotter))
    wait_for(lambda: store.job(1).acked_bytes > 0)
    assert main(["queue", "cancel", "1", "--queue", str(store.path)]) == 0
    wait_for(lambda: store.job(1).state == "cancelled")
    thread.join(20)
    job = store.job(1)
    assert "cancelled (foldfab queue cancel): stopped on request; stopped at byte" in job.reason
    drawn = len(plotter.drawn["sim://a"]) - len(original_strokes(snap))  # job 2 drew everything after
    assert 0 < drawn < len(original_strokes(snap))
    assert store.job(2).state == "done"


def test_disconnect_interrupts_and_the_next_run_resumes_without_losing_a_stroke(store, snapshots):
    snap = snapshots[("grbl", "two-sided")]
    store.add([NewJob(snap, "sim://a"), NewJob(snap, "sim://b")])
    plotter = FakePlotter(fail_at={1: (7, False)})
    summary = Worker(store, Console(["continue"] * 3), WorkerOptions(), runner=plotter).run()
    assert summary.ended == {"interrupted": [1], "done": [2]}  # its own interrupted job waits for the next run
    job = store.job(1)
    assert "serial link failed: cable pulled; stopped at byte" in job.reason and "7 of" in job.reason
    assert main(["queue", "show", "1", "--queue", str(store.path)]) == 0
    interrupted = store.job(1)
    strokes = interpret(snap.program, load_device(snap.device)).strokes
    assert interrupted.drawn_mm == pytest.approx(sum(s.length for s in strokes[:7]))
    summary = Worker(store, Console(["continue"] * 3), WorkerOptions(), runner=plotter).run()
    assert summary.ended == {"done": [1]}
    assert plotter.drawn["sim://a"] == original_strokes(snap)
    # the resumed run's progress counts in the stored program's length, from where it stopped
    done = store.job(1)
    assert (done.drawn_mm, done.drawn_total_mm, done.percent) == pytest.approx(
        (sum(s.length for s in strokes),) * 2 + (100.0,))
    assert "resumed at byte" in [e for e in store.events(1) if e.kind == "started"][1].message


def test_plotter_error_fails_the_job_and_retry_resumes_it(store, snapshots, capsys):
    snap = snapshots[("graphtec-ce6000", "force")]
    store.add([NewJob(snap, "sim://a")])
    plotter = FakePlotter(fail_at={1: (3, True)})
    assert Worker(store, Console(), WorkerOptions(), runner=plotter).run().ended == {"failed": [1]}
    assert "HP-GL error 3" in store.job(1).reason
    assert Worker(store, Console(), WorkerOptions(), runner=plotter).run().ended == {}  # failed jobs wait for retry
    assert main(["queue", "retry", "1", "--queue", str(store.path)]) == 0
    assert "resumes at byte" in capsys.readouterr().out
    assert Worker(store, Console(), WorkerOptions(), runner=plotter).run().ended == {"done": [1]}
    assert plotter.drawn["sim://a"] == original_strokes(snap)


def test_a_job_stopped_after_its_last_stroke_resumes_with_its_closing(store, snapshots):
    """Every stroke acknowledged but the program's last line refused: the job is not done until its
    closing (tool up, head parked) is sent again and confirmed."""
    snap = snapshots[("grbl", "force")]
    store.add([NewJob(snap, f"sim://?time=instant&error_at={snap.program.text.count(chr(10))}")])
    assert Worker(store, Console(), WorkerOptions()).run().ended == {"failed": [1]}
    strokes = interpret(snap.program, load_device(snap.device)).strokes
    assert strokes[-1].end <= store.job(1).acked_bytes < store.job(1).program_bytes
    assert main(["queue", "retry", "1", "--queue", str(store.path)]) == 0
    console = Console()
    assert Worker(store, console, WorkerOptions()).run().ended == {"done": [1]}
    assert f"start 1 all {len(strokes)} strokes were drawn before the interruption: sending the closing" \
        in "\n".join(console.lines)
    assert store.job(1).acked_bytes == store.job(1).program_bytes


def test_port_that_cannot_be_opened_interrupts_without_touching_other_plotters(store, snapshots):
    snap = snapshots[("grbl", "force")]
    store.add([NewJob(snap, "/dev/nonexistent-plotter", 0, 2), NewJob(snap, "sim://b")])
    plotter = FakePlotter()

    def runner(program, device, port, **kw):
        if port.startswith("/dev/"):
            raise PortUnavailable(f"cannot open port {port}: [Errno 2] No such file or directory; check that "
                                  "the plotter is connected")
        plotter(program, device, port, **kw)

    assert Worker(store, Console(), WorkerOptions(), runner=runner).run().ended == \
        {"interrupted": [1], "done": [3]}
    assert "cannot open port /dev/nonexistent-plotter" in store.job(1).reason
    assert store.job(2).state == "queued"  # not tried: job 1 holds that plotter


def test_worker_that_loses_its_job_stops_the_plotter(store, snapshots):
    import sqlite3

    store.add([NewJob(snapshots[("grbl", "force")], "sim://a")])
    plotter = FakePlotter(delay=0.05)
    console = Console()
    thread = in_thread(Worker(store, console, WorkerOptions(heartbeat=0.05), runner=plotter))
    wait_for(lambda: store.job(1).acked_bytes > 0)
    with sqlite3.connect(store.path) as db:  # what another worker does after this one's lease expired
        db.execute("UPDATE jobs SET worker = 'elsewhere/1/x' WHERE id = 1")
    thread.join(20)
    assert any(line.startswith("end 1 lost the job is no longer this worker's") for line in console.lines)
    assert len(plotter.drawn["sim://a"]) < len(original_strokes(snapshots[("grbl", "force")]))
    assert store.job(1).worker == "elsewhere/1/x"


def test_worker_does_not_take_back_a_job_it_lost_in_the_same_run(store, snapshots):
    import sqlite3

    store.add([NewJob(snapshots[("grbl", "force")], "sim://a")])
    plotter = FakePlotter(delay=0.05)
    console = Console()
    summary = {}
    thread = threading.Thread(target=lambda: summary.update(
        Worker(store, console, WorkerOptions(heartbeat=0.05), runner=plotter).run().ended), daemon=True)
    thread.start()
    wait_for(lambda: store.job(1).acked_bytes > 0)
    with sqlite3.connect(store.path) as db:  # the lease ran out (the worker was too slow to renew it)
        db.execute("UPDATE jobs SET lease_expires = 0 WHERE id = 1")
    thread.join(20)
    assert not thread.is_alive() and summary == {"lost": [1]}  # not claimed again, to be lost again
    job = store.job(1)
    assert (job.state, job.attempts) == ("interrupted", 1) and "lease expired" in job.reason


def test_a_lease_shorter_than_a_few_heartbeats_is_refused(store):
    with pytest.raises(ValueError, match=r"the lease \(0.5 s\) must last at least 5 heartbeats \(5 s\)"):
        Worker(store, Console(), WorkerOptions(lease=0.5))
    with pytest.raises(ValueError, match="at least 5 heartbeats"):
        Worker(store, Console(), WorkerOptions(lease=1, heartbeat=0.5))
    Worker(store, Console(), WorkerOptions(lease=1, heartbeat=0.2))


def test_a_job_retried_to_resume_runs_before_a_higher_priority_one_on_its_plotter(store, snapshots, capsys):
    """The repro of the review: the interrupted sheet is on the plotter; queue retry must not let
    another job draw on it."""
    snap = snapshots[("grbl", "force")]
    store.add([NewJob(snap, "sim://a")])
    plotter = FakePlotter(fail_at={1: (5, False)})
    assert Worker(store, Console(), WorkerOptions(), runner=plotter).run().ended == {"interrupted": [1]}
    store.add([NewJob(snapshots[("graphtec-ce6000", "force")], "sim://a", 5)])
    assert main(["queue", "retry", "1", "--queue", str(store.path)]) == 0
    assert "resumes at byte" in capsys.readouterr().out
    assert Worker(store, Console(), WorkerOptions(mode="once"), runner=plotter).run().ended == {"done": [1]}
    assert plotter.drawn["sim://a"] == original_strokes(snap)  # the sheet finished, nothing else on it
    assert store.job(2).state == "queued"


def _damage_first_snapshot(path: Path) -> None:
    import sqlite3

    with sqlite3.connect(path) as db:
        db.execute("UPDATE snapshots SET program = replace(program, 'G1', 'G0') WHERE id = 1")


@pytest.mark.parametrize("dry_run", [False, True])
def test_jobs_with_a_damaged_snapshot_fail_loudly_and_the_others_run(tmp_path, capsys, dry_run):
    queue = ["--queue", str(tmp_path / "q.sqlite3")]
    for copies in ("2", "1"):
        assert main(["queue", "add", str(HEXAGON), "--device", "grbl", "--port", "sim://grbl?time=instant",
                     "--copies", copies, *queue]) == 0
    _damage_first_snapshot(tmp_path / "q.sqlite3")
    capsys.readouterr()
    code = main(["queue", "run", *(["--dry-run"] if dry_run else []), *queue])
    out, err = capsys.readouterr()
    assert code == 2
    for job in (1, 2):
        assert f"job {job} failed: cannot start: job {job}: its stored program does not match its SHA-256" in out
    assert "job 3 done" in out and "2 failed (1, 2); 1 done (3)" in out
    assert err.startswith("foldfab: error: 2 job(s) failed: foldfab queue show ID says why")
    store = SqliteQueueStore(tmp_path / "q.sqlite3")
    expected = ["queued"] * 3 if dry_run else ["failed", "failed", "done"]
    assert [j.state for j in store.jobs()] == expected


def test_threads_running_workers_run_every_job_exactly_once(store, snapshots):
    snap = snapshots[("grbl", "force")]
    store.add([NewJob(snap, f"sim://p{i}", 0, 4) for i in range(3)])
    plotter = FakePlotter(delay=0.001)
    threads = [in_thread(Worker(store, Console(), WorkerOptions(), runner=plotter)) for _ in range(4)]
    for thread in threads:
        thread.join(60)
    assert {j.state for j in store.jobs()} == {"done"}
    for i in range(3):
        assert plotter.drawn[f"sim://p{i}"] == original_strokes(snap) * 4
    assert all(j.attempts == 1 for j in store.jobs())


# --- end to end: the command line, real engines, simulated plotters ------------------------------

FOLDFAB = [sys.executable, "-m", "foldfab"]


def foldfab(*args: str, check: bool = True, **kw) -> subprocess.CompletedProcess:
    result = subprocess.run(FOLDFAB + list(args), capture_output=True, text=True, timeout=300, **kw)
    assert not check or result.returncode == 0, result.stderr
    return result


BUFFER = 64


def small_buffer_profile(folder: Path) -> Path:
    """The HP 7475A with a 64-byte buffer (two or three strokes of the hexagon, instead of 40)."""
    text = (ROOT / "devices" / "hp7475a.toml").read_text()
    assert "\nsize = 1024\n" in text
    path = folder / "hp7475a-small.toml"
    path.write_text(text.replace('name = "hp7475a"', 'name = "hp7475a-small"')
                    .replace("\nsize = 1024\n", f"\nsize = {BUFFER}\n"))
    return path


def sheet_strokes(strokes) -> Counter:
    return Counter(tuple((round(x, 2), round(y, 2)) for x, y in s) for s in strokes)


def test_worker_killed_mid_job_is_resumed_by_the_next_run(tmp_path):
    profile = small_buffer_profile(tmp_path)
    queue, record = tmp_path / "q.sqlite3", tmp_path / "strokes.json"
    sim = subprocess.Popen(FOLDFAB + ["sim", str(profile), "--pty", "--time", "fast", "-o", "speedup=5",
                                      "-o", "sheet=297x210", "--record", str(record)],
                           stdout=subprocess.PIPE, text=True)
    try:
        port = sim.stdout.readline().strip()
        assert port.startswith("/dev/"), port
        foldfab("queue", "add", str(HEXAGON), "--device", str(profile), "--port", port, "--queue", str(queue))
        store = SqliteQueueStore(queue)
        total = store.job(1).program_bytes
        first = subprocess.Popen(FOLDFAB + ["queue", "run", "--queue", str(queue)], stdout=subprocess.DEVNULL,
                                 stderr=subprocess.DEVNULL)
        wait_for(lambda: store.job(1).acked_bytes > 0.4 * total, timeout=60)
        first.send_signal(signal.SIGKILL)
        first.wait()
        job = store.jobs()[0]  # no lease to wait for: the worker's process is gone
        assert job.state == "interrupted" and 0 < job.acked_bytes < total
        # At once, while the plotter still draws what the dead worker left in its buffer: the next run
        # discards the rest (ESC.K), asks where the pen stopped and goes on from there.
        second = foldfab("queue", "run", "--queue", str(queue), check=False)
        assert second.returncode == 0, foldfab("queue", "show", "1", "--queue", str(queue)).stdout
        assert "resumed at stroke" in second.stdout and "job 1 done" in second.stdout
        assert "more stroke(s) after the last acknowledgement" in second.stdout, second.stdout
    finally:
        sim.send_signal(signal.SIGINT)
        sim.communicate(timeout=30)
    strokes = interpret(store.snapshot(1).program, load_device(profile), (297, 210)).strokes
    expected = sheet_strokes(s.points for s in strokes)
    drawn = sheet_strokes(s["points"] for s in json.loads(record.read_text())["strokes"])
    assert not expected - drawn, "a stroke was lost"
    # Drawn twice: only the stroke the plotter was drawing when the next run stopped it.  The sender
    # keeps the pen states in flight unique from the last stroke it reported (test_locate), and the
    # worker saves each reported stroke before the engine goes on, so the pen's stop state is found
    # exactly where it is.
    acked = bisect.bisect_right([s.end for s in strokes], job.acked_bytes)
    located = int(re.search(r"resumed at stroke (\d+) of", second.stdout).group(1)) - 1
    recorded = [np.array(s["points"]) for s in json.loads(record.read_text())["strokes"]]
    first_run = recorded[:len(recorded) - (len(strokes) - located)]
    done = next((i for i, (got, want) in enumerate(zip(first_run, strokes))
                 if got.shape != want.points.shape or not np.allclose(got, want.points, atol=0.01)),
                min(len(first_run), len(strokes)))
    assert acked <= located <= done, "a stroke would be lost"
    assert located == done, (acked, located, done)
    twice = drawn - expected
    assert sum(twice.values()) <= 1, f"drawn twice: {twice}"
    kinds = [e.kind for e in store.events(1)]
    assert kinds == ["queued", "started", "interrupted", "started", "done"]


@pytest.mark.parametrize("device, fault, state, reason", [
    ("hp7475a", "disconnect_after=300", "interrupted", "cable pulled after 300 bytes"),
    ("grbl", "error_at=12", "failed", "GRBL error 20 at program line 12"),
    ("graphtec-ce6000", "error_at=30", "failed", "reports HP-GL error 1 (instruction not recognized)"),
])
def test_faults_of_the_plotter_end_the_job_with_the_reason_and_retry_finishes_it(tmp_path, device, fault,
                                                                                 state, reason):
    queue = ["--queue", str(tmp_path / "q.sqlite3")]
    foldfab("queue", "add", str(HEXAGON), "--device", device, "--port", f"sim://{device}?time=instant&{fault}",
            *queue)
    run = foldfab("queue", "run", *queue, check=False)
    assert run.returncode == 2 and f"1 job(s) {state}" in run.stderr
    shown = foldfab("queue", "show", "1", *queue).stdout
    assert f"state        {state}: " in shown and reason in shown
    foldfab("queue", "retry", "1", "--port", f"sim://{device}?time=instant", *queue)
    assert "job 1 done" in foldfab("queue", "run", *queue).stdout
    kinds = [line.split()[2] for line in foldfab("queue", "show", "1", *queue).stdout.splitlines()
             if line.startswith("  20")]
    assert kinds == ["queued", "started", state, "retried", "started", "done"]


def test_worker_processes_racing_run_every_job_exactly_once(tmp_path):
    queue = ["--queue", str(tmp_path / "q.sqlite3")]
    for index, device in enumerate(["grbl", "hp7475a", "graphtec-ce6000"]):
        foldfab("queue", "add", str(HEXAGON), "--device", device, "--port",
                f"sim://{device}?time=instant&seed={index}", "--copies", "3", *queue)
    workers = [subprocess.Popen(FOLDFAB + ["queue", "run", *queue], stdout=subprocess.PIPE, text=True)
               for _ in range(3)]
    outputs = [worker.communicate(timeout=300)[0] for worker in workers]
    assert all(worker.returncode == 0 for worker in workers), outputs
    store = SqliteQueueStore(tmp_path / "q.sqlite3")
    assert [(j.state, j.attempts) for j in store.jobs()] == [("done", 1)] * 9
    ended = [line.split()[1] for out in outputs for line in out.splitlines()
             if line.startswith("job ") and " done: " in line]
    assert sorted(ended, key=int) == [str(i) for i in range(1, 10)]


def test_dry_run_rehearses_on_simulated_plotters_and_changes_nothing(tmp_path):
    queue = ["--queue", str(tmp_path / "q.sqlite3")]
    foldfab("queue", "add", str(HEXAGON), "--device", "grbl", "--port", "/dev/plotter-not-connected", *queue)
    two_sided = tmp_path / "two.toml"
    two_sided.write_text(HEXAGON.read_text().replace('strategy = "force"', 'strategy = "two-sided"'))
    foldfab("queue", "add", str(two_sided), "--device", "hp7475a", "--port", "/dev/ttyUSB7", *queue)
    before = foldfab("queue", "list", "--json", *queue).stdout
    run = foldfab("queue", "run", "--dry-run", *queue)
    assert "dry run on sim://?time=instant instead of /dev/plotter-not-connected" in run.stdout
    assert "answered by the dry run" in run.stdout and "2 done (1, 2)" in run.stdout
    assert "job 2 pauses: " in run.stdout and "queue continue" not in run.stdout  # nothing to answer
    assert foldfab("queue", "list", "--json", *queue).stdout == before
    assert foldfab("queue", "run", "--once", "--device", "nonesuch", *queue).stdout.startswith("nothing to run")


@pytest.mark.parametrize("mode, rehearsed", [("once", [1]), ("until-empty", [1, 2, 3])])
def test_dry_run_once_rehearses_one_job_as_a_run_would(store, snapshots, mode, rehearsed):
    """Issue 18: ``queue run --dry-run --once`` rehearsed every queued job; --once is one job in both modes."""
    store.add([NewJob(snapshots[("grbl", "force")], "/dev/ttyUSB0")] * 3)
    runner, console = FakePlotter(), Console()
    summary = rehearse(store, console, WorkerOptions(mode=mode), runner=runner)
    assert summary.ended == {"done": rehearsed} and runner.runs == len(rehearsed)
    assert [j.state for j in store.jobs()] == ["queued"] * 3  # a rehearsal changes nothing


def test_cancel_of_a_running_job_lifts_the_tool_on_the_real_engine(store, snapshots):
    from foldfab.plotting.transport import open_port
    from foldfab.plotting.stream import stream

    snap = snapshots[("hp7475a", "perforate")]  # 12 kB: more than the 1 kB buffer, so acknowledged early
    store.add([NewJob(snap, "sim://hp7475a?time=fast&speedup=10")])
    simulators = []

    def runner(program, device, port, **kw):
        link = open_port(port, device)
        simulators.append(link.simulator)
        try:
            stream(link, program, device, **kw)
        finally:
            link.close()

    thread = in_thread(Worker(store, Console(), WorkerOptions(heartbeat=0.05), runner=runner))
    wait_for(lambda: store.job(1).acked_bytes > 0)
    assert main(["queue", "cancel", "1", "--queue", str(store.path)]) == 0
    thread.join(60)
    job = store.job(1)
    assert job.state == "cancelled" and "stopped on request" in job.reason
    plotter = simulators[0]
    assert plotter.machine.stroke is None  # the pen is up
    assert 0 < len(plotter.strokes) < len(original_strokes(snap))


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM", "SIGHUP"])
def test_a_signal_while_the_worker_starts_stops_it_cleanly(sig, tmp_path):
    """The worker's handlers come before its imports: a signal while it starts ends it with exit
    130 and one line, no traceback (it once died of SIGINT, -2, when the handler raised inside
    an import), and the job is not lost: still queued, or, when the worker had claimed it by
    the time the signal came, interrupted to resume."""
    queue = ["--queue", str(tmp_path / "q.sqlite3")]
    foldfab("queue", "add", str(HEXAGON), "--device", "hp7475a", "--port", "sim://hp7475a?time=fast", *queue)
    worker = subprocess.Popen(FOLDFAB + ["queue", "run", *queue], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True)
    wait_for_handler(worker, signal.SIGHUP)
    worker.send_signal(getattr(signal, sig))
    out, err = worker.communicate(timeout=60)
    assert worker.returncode == 130 and err == "foldfab: interrupted\n", err
    assert SqliteQueueStore(tmp_path / "q.sqlite3").job(1).state in ("queued", "interrupted")


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM", "SIGHUP"])
def test_a_signal_stops_the_worker_safely_and_the_job_resumes(sig, tmp_path):
    queue = ["--queue", str(tmp_path / "q.sqlite3")]
    perforated = tmp_path / "perforated.toml"
    perforated.write_text(HEXAGON.read_text().replace('strategy = "force"', 'strategy = "perforate"'))
    foldfab("queue", "add", str(perforated), "--device", "hp7475a", "--port", "sim://hp7475a?time=fast&speedup=5",
            *queue)
    store = SqliteQueueStore(tmp_path / "q.sqlite3")
    worker = subprocess.Popen(FOLDFAB + ["queue", "run", *queue], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True)
    wait_for(lambda: store.job(1).acked_bytes > 0, timeout=60)
    worker.send_signal(getattr(signal, sig))
    out, err = worker.communicate(timeout=60)
    assert worker.returncode == 130 and "Traceback" not in err, out + err
    job = store.job(1)
    assert job.state == "interrupted" and "the worker was stopped: stopped on request" in job.reason
    assert "could not lift" not in job.reason and 0 < job.acked_bytes < job.program_bytes


@pytest.mark.parametrize("typed, state", [(b"\n", "done"), (b"c\n", "cancelled")])
def test_flip_answered_on_the_workers_terminal(tmp_path, typed, state):
    import os
    import pty

    queue = ["--queue", str(tmp_path / "q.sqlite3")]
    two_sided = tmp_path / "two.toml"
    two_sided.write_text(HEXAGON.read_text().replace('strategy = "force"', 'strategy = "two-sided"'))
    foldfab("queue", "add", str(two_sided), "--device", "grbl", "--port", "sim://grbl?time=instant", *queue)
    typist, terminal = pty.openpty()  # the worker reads the terminal side; the test types on the other
    worker = subprocess.Popen(FOLDFAB + ["queue", "run", *queue], stdin=terminal, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True)
    try:
        for line in worker.stdout:
            if line.startswith("press Enter to continue"):
                break
        os.write(typist, typed)
        out, err = worker.communicate(timeout=60)
    finally:
        os.close(typist)
        os.close(terminal)
    store = SqliteQueueStore(tmp_path / "q.sqlite3")
    assert store.job(1).state == state, out + err
    kinds = [e.kind for e in store.events(1)]
    assert kinds == (["queued", "started", "pause", "continued", "done"] if state == "done"
                     else ["queued", "started", "pause", "cancelled"])


def test_a_job_whose_last_run_failed_is_not_located():
    """A plotter error means an instruction was skipped: the plotter's position would place the
    resume past a stroke it did not draw correctly."""
    from foldfab.queue.records import Event
    from foldfab.queue.worker import _failed_last

    def log(*kinds):
        return [Event(float(i), kind, "") for i, kind in enumerate(kinds)]
    assert _failed_last(log("queued", "started", "failed", "retried"))
    assert not _failed_last(log("queued", "started", "failed", "started", "interrupted"))
    assert not _failed_last(log("queued", "started", "interrupted"))
    assert not _failed_last(log("queued"))


def test_an_earlier_save_never_lands_after_a_later_one():
    """The heartbeat thread and the plotting thread (before a pause) both save progress: the
    save that reads the progress first must also write it first (seen: a job waiting at its
    pause with the acknowledged bytes of the stroke before it)."""
    from foldfab.queue.worker import _Heartbeat

    class SlowStore:
        def __init__(self):
            self.saved, self.inside, self.entered, self.release = [], 0, threading.Event(), threading.Event()

        def heartbeat(self, job_id, worker, lease, acked, *rest):
            self.inside += 1
            try:
                if not self.entered.is_set():
                    self.entered.set()
                    assert self.release.wait(60)
                self.saved.append((acked, self.inside))
            finally:
                self.inside -= 1
            return type("Control", (), {"lost": False, "cancel_requested": False})()

    store = SlowStore()
    beat = _Heartbeat(store, None, 1, WorkerOptions(), threading.Event())
    beat.acked = 260
    first = threading.Thread(target=beat.beat)
    first.start()
    assert store.entered.wait(60)
    beat.acked = 270  # the stroke before the pause is acknowledged; the pause saves it
    second = threading.Thread(target=beat.beat)
    second.start()
    second.join(1.0)  # without the lock the second save lands now, before the first
    store.release.set()
    first.join(60)
    second.join(60)
    assert store.saved == [(260, 1), (270, 1)]
class FullDisk:
    """The queue's connection on a disk that fills up when ``full`` is set: from then on every
    commit fails as SQLite fails it (it rolls the transaction back itself, then reports SQLITE_FULL)."""

    def __init__(self, db):
        self.db, self.full = db, False

    def execute(self, sql, *args):
        if sql == "COMMIT" and self.full:
            self.db.execute("ROLLBACK")
            error = sqlite3.OperationalError("database or disk is full")
            error.sqlite_errorname = "SQLITE_FULL"
            raise error
        return self.db.execute(sql, *args)

    def __getattr__(self, name):
        return getattr(self.db, name)


def test_a_full_disk_stops_the_job_at_the_first_progress_save_that_fails(store, snapshots):
    snap = snapshots[("graphtec-ce6000", "force")]
    store.add([NewJob(snap, "sim://a")])
    strokes = original_strokes(snap)
    disk = store._db = FullDisk(store._connect())
    heartbeat, saves = store.heartbeat, []

    def save(*args, **kwargs):  # the worker saves after every stroke: the 4th save finds the disk full
        saves.append(args)
        disk.full = disk.full or len(saves) == 4
        return heartbeat(*args, **kwargs)
    store.heartbeat = save
    plotter, console = FakePlotter(), Console()
    # beats of the heartbeat thread a minute apart: every save here is a stroke's
    summary = Worker(store, console, WorkerOptions(mode="once", heartbeat=60, lease=600), runner=plotter).run()
    assert len(saves) == 4 < len(strokes)
    assert plotter.drawn["sim://a"] == strokes[:4]  # stopped (on request: the tool lifted) before the 5th
    assert summary.ended == {"lost": [1]}
    end = console.lines[-1]
    assert end.startswith("end 1 lost the progress could not be saved: queue file ") and "the disk is full" in end
    assert "the plotter was stopped at byte" in end and "4 of" in end
    disk.full = False  # space freed: the queue holds the last save, so a retry draws again only the 4th stroke
    job = store.job(1)
    assert job.acked_bytes < job.program_bytes
    assert start_point(snap.program, load_device(snap.device), job.acked_bytes, job.pauses_done).stroke == 3
