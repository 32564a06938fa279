"""A plotter farm on one PostgreSQL queue: workers woken by NOTIFY; three hosts (processes) with their
own simulated plotters sharing 200 jobs; a host SIGKILLed at random moments and started again (20
seeded runs); the server restarted mid-run; a worker that loses the server plots on."""

from __future__ import annotations

import os
import random
import threading
from pathlib import Path

import pytest

from foldfab.devices import load_device
from foldfab.programs.program import Program
from foldfab.queue.records import NewJob, WorkerId
from foldfab.queue.snapshot import make_snapshot
from foldfab.queue.postgres import PostgresQueueStore
from foldfab.queue.store import QueueBusy
from foldfab.queue.worker import Worker, WorkerOptions
from helpers.farm import add_jobs, check_farm, run_farm, snapshot
from helpers.processes import wait_for


class Quiet:
    """A worker UI that shows nothing."""

    def job_started(self, job, note): pass
    def progress(self, event): pass
    def paused(self, job, message): pass
    def answer(self, timeout): return None
    def job_ended(self, job, state, message): pass



def test_a_waiting_worker_wakes_at_once_for_a_released_plotter_and_a_new_job(postgres_store):
    """The worker polls only every hour here: what wakes it is the queue's NOTIFY."""
    store = postgres_store
    port = "sim://hp7475a?time=instant"
    store.add([NewJob(snapshot("hp7475a"), port, 0, 2)])
    other = WorkerId(WorkerId.current().host, os.getpid(), "another-worker")
    assert store.claim(other, 3600).job.id == 1  # the plotter is busy with another worker's job
    waits = []
    wait = store.wait_for_work
    store.wait_for_work = lambda timeout, stop: waits.append(timeout) or wait(timeout, stop)
    follower = Worker(store, Quiet(), WorkerOptions(mode="follow", poll=3600.0))
    thread = threading.Thread(target=follower.run, daemon=True)
    thread.start()
    wait_for(lambda: len(waits) >= 2)  # listening, found nothing runnable, waiting
    assert store.job(2).state == "queued"
    store.finish(1, other, "done", "drawn")  # the plotter is released
    wait_for(lambda: store.job(2).state == "done")
    wait_for(lambda: len(waits) >= 3)
    store.add([NewJob(snapshot("hp7475a"), port)])  # a new job
    wait_for(lambda: store.job(3).state == "done")
    assert [f"by worker {follower.id}" in store.events(i)[1].message for i in (2, 3)] == [True, True]
    follower.stop()
    thread.join(10)
    assert not thread.is_alive()


SUITE_KILL_JOBS = 30
"""Jobs of each of the 20 runs with a host killed, in the suite (the plain run and the server
restart have 200): ``python benchmarks/bench_queue.py farm`` runs the 20 kills on 200 jobs each."""


def test_three_hosts_share_one_queue_of_200_jobs(postgres_store):
    """Every job done exactly once, by the host of its plotter, on a plotter of its profile, none lost."""
    rng = random.Random(23)
    assert len(add_jobs(postgres_store, 200, rng)) == 200
    check_farm(postgres_store, 200, run_farm(postgres_store, rng))


@pytest.mark.parametrize("seed", range(20))
def test_a_host_killed_at_a_random_moment_comes_back_and_resumes_its_job(postgres_store, seed):
    """SIGKILL at a seeded random moment (after a random line of a random host's output: between
    jobs, mid-job, or after the last stroke before the end was recorded), the host started again:
    its interrupted job resumes on the same plotter; nothing lost, nothing done twice."""
    rng = random.Random(seed)
    add_jobs(postgres_store, SUITE_KILL_JOBS, rng)
    run = run_farm(postgres_store, rng, kill=True)
    assert run.killed is not None and len(run.pids[run.killed[0]]) == 2
    check_farm(postgres_store, SUITE_KILL_JOBS, run)


class GatedPlotter:
    """A runner that draws stroke by stroke and, before the strokes named in ``gates``, waits until
    the test opens that gate; honours the cancel event at every stroke boundary."""

    def __init__(self, gates: dict[int, threading.Event]):
        self.gates = gates
        self.reached = {index: threading.Event() for index in gates}
        self.drawn = 0

    def __call__(self, program, device, port, *, events, cancel, operator):
        from foldfab.plotting.engines.base import StreamStopped
        from foldfab.plotting.progress import JobProgress

        progress, acked = JobProgress(program, device), 0
        events(progress.event("start", 0, 0, 0.0))
        for index, stroke in enumerate(progress.strokes):
            if index in self.gates:
                self.reached[index].set()
                assert self.gates[index].wait(120)
            if cancel.is_set():
                raise StreamStopped("stopped on request", acknowledged=acked, pauses_done=0, cancelled=True,
                                    lifted=True)
            self.drawn += 1
            acked = stroke.end
            events(progress.event("progress", acked, acked, 0.1 * index))
        events(progress.event("done", len(program.text), len(program.text), 1.0))


def outage_setup(store):
    """One four-stroke job; heartbeats and finishes that fail, counted."""
    profile = load_device("hp7475a")
    program = Program("IN;SP1;PU0,0;PD400,0;PU0,100;PD400,100;PU0,200;PD400,200;PU0,300;PD400,300;SP0;",
                      "hpgl", profile.name, (), ())
    store.add([NewJob(make_snapshot(Path("farm.toml"), "[design]\n", "outage", profile, program), "sim://gated")])
    failures, controls = [], []
    for name in ("heartbeat", "finish"):
        def counted(*args, _call=getattr(store, name), _name=name, **kw):
            try:
                result = _call(*args, **kw)
            except QueueBusy:
                failures.append(_name)
                raise
            controls.append(result)
            return result
        setattr(store, name, counted)
    return failures, controls


@pytest.fixture()
def own_server():
    """A server of the test's own, to stop and start again."""
    from helpers.postgres import running_server

    with running_server() as server:
        yield server


def test_a_worker_plots_on_while_the_server_is_down_and_saves_its_progress_after(own_server):
    store = PostgresQueueStore(own_server.new_database(), wait=0.5)
    failures, _ = outage_setup(store)
    go = threading.Event()
    plotter = GatedPlotter({1: go})
    worker = Worker(store, Quiet(), WorkerOptions(heartbeat=0.1, lease=1.0), runner=plotter, locate=False)
    ended = []
    thread = threading.Thread(target=lambda: ended.append(worker.run()), daemon=True)
    thread.start()
    assert plotter.reached[1].wait(120)
    own_server.stop("immediate")  # the server is gone (a power cut)
    wait_for(lambda: failures.count("heartbeat") >= 4)  # longer than the 1 s lease: 0.1+0.2+0.4+0.8 s backing off
    go.set()  # the plotter draws on, offline, to the end of the sheet
    wait_for(lambda: "finish" in failures)
    assert plotter.drawn == 4 and thread.is_alive()
    own_server.start()
    thread.join(120)
    assert ended and ended[0].ended == {"done": [1]}
    job = store.job(1)
    assert (job.state, job.acked_bytes, job.attempts) == ("done", job.program_bytes, 1)
    assert [e.kind for e in store.events(1)] == ["queued", "started", "interrupted", "reconnected", "done"]
    store.close()


def test_a_worker_whose_job_was_taken_while_the_server_was_down_stops_at_the_next_stroke(own_server):
    store = PostgresQueueStore(own_server.new_database(), wait=0.5)
    failures, controls = outage_setup(store)
    first, second = threading.Event(), threading.Event()
    plotter = GatedPlotter({1: first, 2: second})
    worker = Worker(store, Quiet(), WorkerOptions(heartbeat=0.1, lease=1.0), runner=plotter, locate=False)
    ended = []
    thread = threading.Thread(target=lambda: ended.append(worker.run()), daemon=True)
    thread.start()
    assert plotter.reached[1].wait(120)
    own_server.stop("immediate")
    wait_for(lambda: failures.count("heartbeat") >= 4)
    first.set()
    assert plotter.reached[2].wait(120)
    own_server.start()
    other = PostgresQueueStore(store.url)
    taken = other.claim(WorkerId("another-host", 1, "x"), 30)  # the lease had lapsed: another worker takes it
    assert taken is not None and taken.job.id == 1 and taken.job.acked_bytes > 0
    wait_for(lambda: any(c.lost for c in controls))  # the worker's next heartbeat learns it
    second.set()
    thread.join(120)
    assert plotter.drawn == 2  # stopped at the stroke boundary after it learnt it
    assert ended and ended[0].ended == {"lost": [1]}
    assert (store.job(1).state, store.job(1).worker) == ("running", "another-host/1/x")
    other.close()
    store.close()


def test_the_hosts_wait_out_a_server_restart_and_finish_every_job(own_server):
    """pg_ctl restart while three hosts plot 200 jobs: their connections are cut, they reconnect
    backing off (a claim, a heartbeat, the end of a job) and finish everything, each job once."""
    store = PostgresQueueStore(own_server.new_database())
    rng = random.Random(5)
    add_jobs(store, 200, rng)
    run = run_farm(store, rng, restart=own_server.restart)
    assert run.restarted_after is not None
    check_farm(store, 200, run)
    assert "database system is shut down" in own_server.log.read_text()  # it was restarted
    store.close()


def test_a_worker_waits_out_a_server_it_cannot_reach_to_claim_or_start_a_job(postgres_store):
    """A host between jobs when the server restarts: its claim, then its read of the job's log
    before starting, fail while the server is away; it tries again backing off, and plots."""
    store = postgres_store
    store.add([NewJob(snapshot("hp7475a"), "sim://hp7475a?time=instant")])
    failures = []
    for name, fails in (("claim", 2), ("events", 1)):
        def away(*args, _call=getattr(store, name), _name=name, _fails=fails, **kw):
            if failures.count(_name) < _fails:
                failures.append(_name)
                raise QueueBusy("queue server: the database system is shutting down")
            return _call(*args, **kw)
        setattr(store, name, away)
    worker = Worker(store, Quiet(), WorkerOptions(heartbeat=0.05, lease=1.0))
    assert worker.run().ended == {"done": [1]}
    assert failures == ["claim", "claim", "events"]
    assert [e.kind for e in store.events(1)] == ["queued", "started", "done"]


def test_a_claim_holds_its_snapshot_when_the_server_goes_away_just_after(postgres_store):
    """The snapshot is read in the claim's transaction: a server lost once the claim committed
    cannot make a sound job look damaged (the worker would fail it)."""
    store = postgres_store
    store.add([NewJob(snapshot("hp7475a"), "sim://p")])

    def gone():
        raise QueueBusy("queue server: terminating connection due to administrator command")
    store._read = gone  # every read after the claim's own transaction
    claim = store.claim(WorkerId.current(), 30)
    assert claim.damage is None and claim.snapshot.program.text.startswith("IN;")
