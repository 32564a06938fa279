"""Job queue speed, end to end through the command line (a new Python process each time).

Run by hand:  python benchmarks/bench_queue.py
Targets: ``foldfab queue list`` with 10,000 jobs <= 0.3 s; ``foldfab queue add`` of a paper-scale job <= 0.5 s.
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


if __name__ == "__main__":
    cache_foldfab_bytecode()
    main()
