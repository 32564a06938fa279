"""A plotter farm on one PostgreSQL queue: workers woken by NOTIFY, hosts (processes) with their own
simulated plotters sharing the jobs, a host killed mid-run and started again."""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from foldfab.devices import load_device
from foldfab.programs.program import Program
from foldfab.queue.records import NewJob, WorkerId
from foldfab.queue.snapshot import make_snapshot
from foldfab.queue.postgres import PostgresQueueStore
from foldfab.queue.store import QueueBusy
from foldfab.queue.worker import Worker, WorkerOptions
from helpers import ROOT

HPGL = "IN;SP1;PU0,0;PD400,0,400,400,0,400,0,0;PU800,0;PD1200,0,1200,400;SP0;"


def snapshot(device: str):
    profile = load_device(device)
    return make_snapshot(Path("farm.toml"), "[design]\n", f"farm job for {device}", profile,
                         Program(HPGL, "hpgl", profile.name, (), ()))


class Quiet:
    """A worker UI that shows nothing."""

    def job_started(self, job, note): pass
    def progress(self, event): pass
    def paused(self, job, message): pass
    def answer(self, timeout): return None
    def job_ended(self, job, state, message): pass


def wait_for(condition, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.02)  # poll interval


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


def host(url: str, port: str) -> subprocess.Popen:
    """One host of the farm: ``foldfab queue run`` for its plotter, in its own process."""
    return subprocess.Popen([sys.executable, "-m", "foldfab", "queue", "run", "--port", port, "--lease", "30"],
                            env=dict(os.environ, FOLDFAB_QUEUE=url), cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


FARM = {"a": "hp7475a", "b": "graphtec-ce6000", "c": "hp7475a"}


@pytest.mark.parametrize("seed", [1, 2])
def test_three_hosts_share_one_queue_and_a_killed_host_resumes(postgres_store, seed):
    """60 jobs for three plotters on three hosts: every job done exactly once on its plotter, the
    job of the host killed at a random moment resumed when it comes back, nothing lost."""
    store, rng = postgres_store, random.Random(seed)
    ports = {name: f"sim://{device}?time=instant&session={name}" for name, device in FARM.items()}
    ids = store.add([NewJob(snapshot(FARM[name]), ports[name], rng.randint(0, 2), 20) for name in FARM])
    assert len(ids) == 60
    hosts = {name: host(store.url, port) for name, port in ports.items()}
    victim_done, running = rng.randint(1, 15), []

    def mid_job() -> bool:  # a random number of jobs done on host c, and one running there
        on_c = [j for j in store.jobs() if j.port == ports["c"]]
        running[:] = [j.id for j in on_c if j.state == "running"]
        return sum(j.state == "done" for j in on_c) >= victim_done and bool(running)
    wait_for(mid_job)
    hosts["c"].send_signal(signal.SIGKILL)
    hosts["c"].wait(30)
    hosts["c"] = host(store.url, ports["c"])  # the host comes back
    for name, process in hosts.items():
        out, err = process.communicate(timeout=300)
        assert process.returncode == 0, (name, out, err)
    jobs = store.jobs()
    assert [j.state for j in jobs] == ["done"] * 60
    for job in jobs:
        kinds = [e.kind for e in store.events(job.id)]
        assert kinds.count("done") == 1
        assert job.device == FARM[job.port.split("session=")[1]]
        assert job.acked_bytes == job.program_bytes
        # at most one interruption (the killed host's job), then a resume on the same plotter
        assert kinds in (["queued", "started", "done"], ["queued", "started", "interrupted", "started", "done"])
        assert job.id in running or kinds == ["queued", "started", "done"]


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
