"""Job queue speed, end to end through the command line (a new Python process each time), and the
claim throughput of many workers on one queue, PostgreSQL against SQLite.

Run by hand:  python benchmarks/bench_queue.py
              python benchmarks/bench_queue.py claims [--workers 16] [--jobs 3200] [--postgres URL]
              python benchmarks/bench_queue.py list [--jobs 100000] [--postgres URL]
              python benchmarks/bench_queue.py farm [--runs 20] [--jobs 200]
Targets: ``foldfab queue list`` with 10,000 jobs <= 0.3 s; ``foldfab queue add`` of a paper-scale job <= 0.5 s.
``claims``: WORKERS processes (each its own store, as hosts have) claim and finish JOBS jobs spread
over many plotters; claims per second overall and the claim latency (median, 99th percentile), on a
PostgreSQL server (URL, else a throw-away one started as the tests do) and on an SQLite file.
``list``: a queue of JOBS jobs (filled in one statement), ``foldfab queue list`` end to end (its first
page) and the store call alone, on both stores. Target: 100,000 jobs on PostgreSQL <= 0.3 s.
``farm``: the farm test at full scale (the suite kills hosts in runs of fewer jobs): three hosts, JOBS
jobs, RUNS runs each with a host SIGKILLed at a seeded random moment and started again, then one
with the server restarted (pg_ctl restart); every job checked done exactly once on its plotter.
"""

from __future__ import annotations

import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from warm_bytecode import cache_foldfab_bytecode

ROOT = Path(__file__).resolve().parent.parent
FOLDFAB = [sys.executable, "-m", "foldfab"]
REPEAT = 7


def timed(command: list[str], repeat: int = REPEAT) -> tuple[float, float]:
    """Median and best wall time of the command, which must succeed."""
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
        times.append(time.perf_counter() - start)
    return statistics.median(times), min(times)


def fill(queue: Path, count: int) -> None:
    """``count`` jobs, each with its own snapshot of a paper job's program; a mix of states."""
    from foldfab.design import load_design
    from foldfab.devices import load_device
    from foldfab.fabricate import fabricate
    from foldfab.queue.records import NewJob, WorkerId
    from foldfab.queue.snapshot import make_snapshot
    from foldfab.queue.sqlite import SqliteQueueStore

    device = load_device("graphtec-ce6000")
    job = ROOT / "jobs" / "hexagon-fig8a.toml"
    design = load_design(job)
    snapshot = make_snapshot(job, design.job.text, design.job.name, device, fabricate(design, device).program)
    store = SqliteQueueStore(queue)
    store.add([NewJob(snapshot, f"/dev/ttyUSB{i % 4}", i % 3) for i in range(count)])
    worker = WorkerId.current()
    for _ in range(3):  # a few running, the rest queued; some done
        store.claim(worker, 3600)
    for job_id in range(10, count, 3):
        store.cancel(job_id)
    store.close()


def main() -> None:
    folder = Path(tempfile.mkdtemp(prefix="foldfab-bench-queue-"))
    try:
        queue = folder / "queue.sqlite3"
        fill(queue, 10_000)
        size = queue.stat().st_size + sum(p.stat().st_size for p in folder.glob("queue.sqlite3-*"))
        q = ["--queue", str(queue)]
        rows = [
            ("foldfab --help (start-up alone)", ["--help"]),
            ("python -c 'import vpype' (the floor of any build)", None),
            ("queue list, 10,000 jobs", ["queue", "list", *q]),
            ("queue list --state queued, 10,000 jobs", ["queue", "list", "--state", "queued", *q]),
            ("queue list --json, 10,000 jobs", ["queue", "list", "--json", *q]),
            ("queue show 5000", ["queue", "show", "5000", *q]),
            ("export hexagon-fig8a (for comparison: the same build)",
             ["export", str(ROOT / "jobs" / "hexagon-fig8a.toml"), "--device", "graphtec-ce6000",
              "-o", str(folder / "out.hpgl")]),
            ("queue add hexagon-fig8a (Fig. 8 a), graphtec-ce6000",
             ["queue", "add", str(ROOT / "jobs" / "hexagon-fig8a.toml"), "--device", "graphtec-ce6000", *q]),
            ("queue add diamond-fig9 (Fig. 9), hp7475a",
             ["queue", "add", str(ROOT / "jobs" / "diamond-fig9.toml"), "--device", "hp7475a", *q]),
            ("queue add helix-fig12 (Fig. 12), grbl",
             ["queue", "add", str(ROOT / "jobs" / "helix-fig12.toml"), "--device", "grbl", *q]),
        ]
        print(f"queue file: 10,000 jobs, {size / 1e6:.1f} MB; wall time per command, median (best) of {REPEAT}")
        print(f"{'command':<56}{'median s':>10}{'best s':>9}")
        for label, args in rows:
            median, best = timed(FOLDFAB + args if args else [sys.executable, "-c", "import vpype"])
            print(f"{label:<56}{median:>10.3f}{best:>9.3f}")
    finally:
        shutil.rmtree(folder)


def _claimer(location: str, start, results) -> None:
    """One worker: claim and finish until nothing is left; the latency of every claim (a claim
    that found the queue busy is tried again, its time counted), and how many were busy."""
    from foldfab.queue.location import open_queue
    from foldfab.queue.records import WorkerId
    from foldfab.queue.store import QueueBusy

    store, worker, latencies, busy = open_queue(location, wait=10), WorkerId.current(), [], 0
    store.jobs("running")  # connect before the clock starts
    start.wait()
    while True:
        began = time.perf_counter()
        while True:
            try:
                claim = store.claim(worker, 600)
                break
            except QueueBusy:
                busy += 1
        latencies.append(time.perf_counter() - began)
        if claim is None:
            break
        while True:
            try:
                store.finish(claim.job.id, worker, "done", "benchmark")
                break
            except QueueBusy:
                busy += 1
    store.close()
    results.put((latencies[:-1], busy))


def claims(location: str, workers: int, jobs: int) -> tuple[float, float, float, int]:
    """Claims per second, median and 99th-percentile claim latency (s) of ``workers`` processes, and
    how many of their operations found the queue busy (tried again)."""
    import multiprocessing

    from foldfab.devices import load_device
    from foldfab.programs.program import Program
    from foldfab.queue.location import open_queue
    from foldfab.queue.records import NewJob
    from foldfab.queue.snapshot import make_snapshot

    device = load_device("hp7475a")
    snap = make_snapshot(Path("bench.toml"), "[design]\n", "bench", device,
                         Program("IN;SP1;PU0,0;PD400,400;SP0;", "hpgl", device.name, (), ()))
    store = open_queue(location)
    plotters = 8 * workers
    store.add([NewJob(snap, f"sim://p{i}", 0, jobs // plotters) for i in range(plotters)])
    store.close()
    context = multiprocessing.get_context("spawn")
    start, results = context.Barrier(workers + 1), context.Queue()
    processes = [context.Process(target=_claimer, args=(location, start, results)) for _ in range(workers)]
    for process in processes:
        process.start()
    start.wait()  # every worker has connected
    began = time.perf_counter()
    answers = [results.get(timeout=1800) for _ in processes]
    elapsed = time.perf_counter() - began
    latencies = [x for times, _ in answers for x in times]
    for process in processes:
        process.join(60)
    latencies.sort()
    assert len(latencies) == plotters * (jobs // plotters), "a job was claimed twice or not at all"
    return (len(latencies) / elapsed, statistics.median(latencies), latencies[int(0.99 * (len(latencies) - 1))],
            sum(busy for _, busy in answers))


def main_claims(argv: list[str]) -> None:
    import argparse

    parser = argparse.ArgumentParser(prog="bench_queue.py claims")
    parser.add_argument("--workers", type=int, default=16)
    parser.add_argument("--jobs", type=int, default=3200)
    parser.add_argument("--postgres", metavar="URL", help="an empty database (default: a throw-away server)")
    args = parser.parse_args(argv)
    args.postgres, server = throwaway_server(args.postgres)
    folder = Path(tempfile.mkdtemp(prefix="foldfab-bench-claims-"))
    try:
        print(f"{args.workers} worker processes claim and finish {args.jobs} jobs on {8 * args.workers} plotters")
        print(f"{'queue':<12}{'claims/s':>10}{'median ms':>11}{'p99 ms':>9}{'busy':>7}")
        for label, location in (("PostgreSQL", args.postgres), ("SQLite", str(folder / "queue.sqlite3"))):
            rate, median, p99, busy = claims(location, args.workers, args.jobs)
            print(f"{label:<12}{rate:>10.0f}{1000 * median:>11.1f}{1000 * p99:>9.1f}{busy:>7}", flush=True)
    finally:
        shutil.rmtree(folder)
        if server is not None:
            server.destroy()


def throwaway_server(url: str | None):
    """``url``, else a throw-away PostgreSQL server's new database (and the server, to destroy)."""
    if url:
        return url, None
    sys.path.insert(0, str(ROOT / "tests"))
    from helpers.postgres import PostgresServer

    server = PostgresServer().start()
    return server.new_database(), server


def in_process(call, repeat: int = 20) -> float:
    """Median wall time of ``call()`` in this process."""
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main_list(argv: list[str]) -> None:
    import argparse

    parser = argparse.ArgumentParser(prog="bench_queue.py list")
    parser.add_argument("--jobs", type=int, default=100_000)
    parser.add_argument("--postgres", metavar="URL", help="an empty database (default: a throw-away server)")
    args = parser.parse_args(argv)
    url, server = throwaway_server(args.postgres)
    sys.path.insert(0, str(ROOT / "tests"))
    from helpers.queues import fill_jobs

    from foldfab.devices import load_device
    from foldfab.programs.program import Program
    from foldfab.queue.location import open_queue
    from foldfab.queue.snapshot import make_snapshot

    device = load_device("hp7475a")
    snap = make_snapshot(Path("bench.toml"), "[design]\n", "bench", device,
                         Program("IN;SP1;PU0,0;PD400,400;SP0;", "hpgl", device.name, (), ()))
    folder = Path(tempfile.mkdtemp(prefix="foldfab-bench-list-"))
    try:
        print(f"queue list of {args.jobs} jobs (7 in 10 done, 2 queued); wall time, median (best) of {REPEAT}; "
              "the store call alone: median of 20")
        print(f"{'queue':<12}{'what':<52}{'median s':>10}{'best s':>9}")
        for what, command in (("python -c 'import vpype' (the yardstick)", [sys.executable, "-c", "import vpype"]),
                              ("foldfab --help (start-up alone)", FOLDFAB + ["--help"])):
            median, best = timed(command)
            print(f"{'':<12}{what:<52}{median:>10.3f}{best:>9.3f}", flush=True)
        for label, location in (("PostgreSQL", url), ("SQLite", str(folder / "queue.sqlite3"))):
            store = open_queue(location)
            began = time.perf_counter()
            fill_jobs(store, snap, args.jobs)
            print(f"{label:<12}{'(filled in one statement)':<52}{time.perf_counter() - began:>10.3f}")
            middle = args.jobs // 2
            for what, extra in (("foldfab queue list (first page of 100)", []),
                                (f"foldfab queue list --after {middle}", ["--after", str(middle)]),
                                ("foldfab queue list --state queued", ["--state", "queued"]),
                                ("foldfab queue list --limit 0 (every job)", ["--limit", "0"])):
                median, best = timed(FOLDFAB + ["queue", "list", "--queue", location, *extra],
                                     repeat=REPEAT if extra[-1:] != ["0"] else 3)
                print(f"{label:<12}{what:<52}{median:>10.3f}{best:>9.3f}", flush=True)
            for what, call in (("store.page(limit=100)", lambda: store.page(None, 0, 100)),
                               (f"store.page(after={middle}, limit=100)", lambda: store.page(None, middle, 100)),
                               ("store.page('queued', limit=100)", lambda: store.page("queued", 0, 100))):
                print(f"{label:<12}{what:<52}{in_process(call):>10.4f}", flush=True)
            store.close()
    finally:
        shutil.rmtree(folder)
        if server is not None:
            server.destroy()


def main_farm(argv: list[str]) -> None:
    import argparse
    import random

    parser = argparse.ArgumentParser(prog="bench_queue.py farm")
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--jobs", type=int, default=200)
    args = parser.parse_args(argv)
    sys.path.insert(0, str(ROOT / "tests"))
    from helpers.farm import add_jobs, check_farm, run_farm
    from helpers.postgres import running_server

    from foldfab.queue.postgres import PostgresQueueStore

    with running_server() as server:
        print(f"three hosts, {args.jobs} jobs a run, one PostgreSQL queue (seed: the run's number)")
        print(f"{'run':<34}{'killed (host, after line)':<28}{'interrupted':>12}{'s':>8}")
        for seed in [*range(args.runs), "restart"]:
            store = PostgresQueueStore(server.new_database())
            rng = random.Random(seed)
            add_jobs(store, args.jobs, rng)
            began = time.perf_counter()
            if seed == "restart":
                run = run_farm(store, rng, restart=server.restart)
            else:
                run = run_farm(store, rng, kill=True)
            elapsed = time.perf_counter() - began
            check_farm(store, args.jobs, run)
            resumed = [j.id for j in store.jobs() if j.attempts > 1]
            label = f"server restarted after line {run.restarted_after}" if seed == "restart" else f"seed {seed}"
            print(f"{label:<34}{str(run.killed or '-'):<28}{str(resumed or '-'):>12}{elapsed:>8.1f}", flush=True)
            store.close()
    print(f"all {args.runs + 1} runs: every job done exactly once, by the host of its plotter, none lost")


if __name__ == "__main__":
    cache_foldfab_bytecode()
    if sys.argv[1:2] == ["claims"]:
        main_claims(sys.argv[2:])
    elif sys.argv[1:2] == ["list"]:
        main_list(sys.argv[2:])
    elif sys.argv[1:2] == ["farm"]:
        main_farm(sys.argv[2:])
    else:
        main()
