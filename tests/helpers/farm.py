"""A plotter farm on one PostgreSQL queue, for the farm tests and ``benchmarks/bench_queue.py farm``:
hosts (each a ``foldfab queue run`` process for its own simulated plotter) share the queue's jobs;
a host may be SIGKILLed at a seeded random moment and started again, and the server restarted.
Every wait is on an event (a line a host prints, a process ending) and bounded."""

from __future__ import annotations

import os
import random
import re
import signal
import subprocess
import sys
import threading
from dataclasses import dataclass, field
from pathlib import Path

from helpers import ROOT

FARM = {"a": "hp7475a", "b": "graphtec-ce6000", "c": "hp7475a"}
"""Host name -> the profile of its one plotter (two hosts share a profile)."""
HPGL = "IN;SP1;PU0,0;PD400,0,400,400,0,400,0,0;PU800,0;PD1200,0,1200,400;SP0;"
LINES_PER_JOB = 4
"""What ``queue run`` prints for a job: started, two progress lines, the end."""
TIMEOUT = 300.0
"""Longest wait for any one event of a farm run (a host's line, a host's end)."""


def ports() -> dict[str, str]:
    """Host name -> the port of its simulated plotter (its own session)."""
    return {name: f"sim://{device}?time=instant&session={name}" for name, device in FARM.items()}


def snapshot(device: str):
    from foldfab.devices import load_device
    from foldfab.programs.program import Program
    from foldfab.queue.snapshot import make_snapshot

    profile = load_device(device)
    return make_snapshot(Path("farm.toml"), "[design]\n", f"farm job for {device}", profile,
                         Program(HPGL, "hpgl", profile.name, (), ()))


def add_jobs(store, count: int, rng: random.Random) -> list[int]:
    """``count`` jobs, each for a random host's plotter with a random priority, in one transaction."""
    from foldfab.queue.records import NewJob

    snapshots, where = {d: snapshot(d) for d in set(FARM.values())}, ports()
    names = [rng.choice(sorted(FARM)) for _ in range(count)]
    return store.add([NewJob(snapshots[FARM[name]], where[name], rng.randint(0, 2)) for name in names])


class Host:
    """One host: ``foldfab queue run --port PORT`` in its own process; its output read as it comes."""

    def __init__(self, url: str, name: str):
        self.name = name
        self.process = subprocess.Popen(
            [sys.executable, "-m", "foldfab", "queue", "run", "--port", ports()[name], "--lease", "30"],
            env=dict(os.environ, FOLDFAB_QUEUE=url), cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            text=True)
        self.lines: list[str] = []
        self.errors = ""
        self._changed = threading.Condition()
        self._readers = [threading.Thread(target=self._read, daemon=True),
                         threading.Thread(target=self._read_errors, daemon=True)]
        for reader in self._readers:
            reader.start()

    def _read(self) -> None:
        for line in self.process.stdout:
            with self._changed:
                self.lines.append(line.rstrip("\n"))
                self._changed.notify_all()
        with self._changed:
            self.lines.append(None)  # the end of its output
            self._changed.notify_all()

    def _read_errors(self) -> None:
        self.errors = self.process.stderr.read()

    def wait_lines(self, count: int, timeout: float = TIMEOUT) -> bool:
        """Wait until the host printed ``count`` lines (True) or ended before (False)."""
        with self._changed:
            assert self._changed.wait_for(lambda: len(self.lines) >= count or None in self.lines, timeout), \
                f"host {self.name} printed {len(self.lines)} lines in {timeout} s, not {count}"
            return None not in self.lines[:count]

    def kill(self) -> None:
        self.process.send_signal(signal.SIGKILL)
        self.process.wait(TIMEOUT)
        self.end()

    def end(self, timeout: float = TIMEOUT) -> int:
        """Wait for the host to finish; its exit code."""
        code = self.process.wait(timeout)
        for reader in self._readers:
            reader.join(timeout)
        return code


@dataclass
class FarmRun:
    """What happened in one run: the pids of each host's processes, which host was killed after
    which of its lines (if one was), and whether the server was restarted."""

    pids: dict[str, set[int]] = field(default_factory=dict)
    killed: tuple[str, int] | None = None
    restarted_after: int | None = None


def run_farm(store, rng: random.Random, kill: bool = False, restart=None) -> FarmRun:
    """Start the three hosts on ``store``'s queue and wait until each has run out of jobs.
    ``kill``: SIGKILL a random host after a random line of its output (any moment of its run),
    then start it again; ``restart``: a function that restarts the server, called likewise after
    a random line of host a's output."""
    jobs = {name: sum(job.port == port for job in store.jobs()) for name, port in ports().items()}
    hosts = {name: Host(store.url, name) for name in FARM}
    run = FarmRun({name: {host.process.pid} for name, host in hosts.items()})
    if restart is not None:
        run.restarted_after = rng.randint(1, LINES_PER_JOB * max(jobs["a"], 1))
        hosts["a"].wait_lines(run.restarted_after)
        restart()
    if kill:
        victim = rng.choice(sorted(FARM))
        run.killed = (victim, rng.randint(1, LINES_PER_JOB * max(jobs[victim], 1)))
        hosts[victim].wait_lines(run.killed[1])
        hosts[victim].kill()
        hosts[victim] = Host(store.url, victim)  # the host comes back
        run.pids[victim].add(hosts[victim].process.pid)
    for name, host in hosts.items():
        code = host.end()
        assert code == 0, (name, code, host.lines[-5:], host.errors)
    return run


def check_farm(store, count: int, run: FarmRun) -> None:
    """Every job done exactly once, by the host of its plotter, on a plotter of its profile; none
    lost; a job interrupted only on the killed host's plotter, and then resumed there."""
    jobs = store.jobs()
    assert len(jobs) == count
    assert [job.state for job in jobs] == ["done"] * count, [(j.id, j.state, j.reason) for j in jobs
                                                             if j.state != "done"]
    where = {port: name for name, port in ports().items()}
    interrupted = []
    for job in jobs:
        events = store.events(job.id)
        kinds = [event.kind for event in events]
        name = where[job.port]
        assert job.device == FARM[name] and job.drawn_mm == job.drawn_total_mm > 0  # every stroke drawn
        assert kinds.count("done") == 1 and kinds[-1] == "done"
        workers = [int(re.search(r"by worker [^/ ]+/(\d+)/", e.message).group(1))
                   for e in events if e.kind == "started"]
        assert workers and set(workers) <= run.pids[name], (job.id, workers, run.pids)
        if kinds == ["queued", "started", "done"]:
            assert job.acked_bytes == job.program_bytes
        else:
            # a killed host's job: interrupted, then resumed on the same plotter, by that host again
            # (killed after its last stroke, the resume has nothing left to draw and ends there:
            # the bytes after the last stroke, pen put away, are then not sent)
            assert kinds == ["queued", "started", "interrupted", "started", "done"], (job.id, kinds)
            interrupted.append(job.id)
            assert run.killed and name == run.killed[0], (job.id, kinds, run)
    assert len(interrupted) <= 1  # one kill, one job at most on that host's plotter
