"""The 1,000,000-face roll: CPU seconds and peak memory of ``foldfab design --fold`` and ``foldfab export``.

Run by hand:  python benchmarks/bench_scale.py [ROUNDS] [--base FOLDER]

The job is the export benchmark's 101,000-face zigzag roll (``bench_fabrication.export_cases``)
with ten times the corners on ten times the radius: 1,001 profile points x 1,000 corners,
1,001,000 faces, a 125.7 m roll on a cutter profile reaching 130 m.  Each command runs in
turns with the yardstick ``python -c "import vpype"``; each figure is the median over ROUNDS
(default 3) of its wall seconds, CPU seconds (user + system: on a busy machine wall time says
more about the neighbours) and peak resident memory (``wait4``'s ``ru_maxrss``).  ``--base
FOLDER`` also runs an unpacked other version of foldfab (``git archive COMMIT | tar -x -C
FOLDER``) in the same turns, for before/after figures.  ``export (optimize none)`` leaves the
stroke sort out, whose cost is its own benchmark's (bench_fabrication.py).
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def write_jobs(tmp: Path) -> dict[str, list[str]]:
    """The 1,000,000-face job, its unsorted twin and the roll profile in ``tmp``: each case's arguments."""
    points = ", ".join(f"[{0.03 * (i % 2)}, {0.05 * i:.2f}]" for i in range(1001))
    job = (f"[profile]\npoints = [{points}]\n[trajectory]\ntemplate = \"regular\"\ncorners = 1000\n"
           "radius = 20000\n[fabrication]\nsheet = [130000, 100]\nmargin = 5\n")
    (tmp / "huge.toml").write_text(job)
    (tmp / "huge-unsorted.toml").write_text(job + "optimize = \"none\"\n")
    profile = (ROOT / "devices" / "graphtec-ce6000.toml").read_text()
    (tmp / "roll.toml").write_text(profile.replace('name = "graphtec-ce6000"', 'name = "huge-roll"')
                                   .replace("plottable_area = [1000, 375]", "plottable_area = [375, 130000]"))
    return {"design --fold": ["design", str(tmp / "huge.toml"), "--fold", str(tmp / "huge.fold")],
            "export (optimize none)": ["export", str(tmp / "huge-unsorted.toml"), "--device", str(tmp / "roll.toml"),
                                       "-o", str(tmp / "huge.plt")],
            "export": ["export", str(tmp / "huge.toml"), "--device", str(tmp / "roll.toml"), "-o", str(tmp / "huge.plt")]}


def measure(command: list[str], env: dict[str, str], folder: Path) -> tuple[float, float, float]:
    """Wall seconds, CPU seconds and peak MB of one run in ``folder`` (not the repository:
    ``python -m`` would import its foldfab whatever PYTHONPATH says); it must succeed."""
    start = time.perf_counter()
    child = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env, cwd=folder)
    _, status, usage = os.wait4(child.pid, 0)
    wall = time.perf_counter() - start
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(command)} failed: {child.stderr.read().decode()}")
    child.stderr.close()
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024


def main(rounds: int, base: Path | None, cases: list[str]) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        jobs = write_jobs(Path(tmp))
        versions = {"this": dict(os.environ)}
        if base is not None:
            versions[f"base ({base})"] = dict(os.environ, PYTHONPATH=str(base))
        runs: dict[tuple[str, str], list[tuple[float, float, float]]] = {}
        yardstick = []
        for _ in range(rounds):
            yardstick.append(measure([sys.executable, "-c", "import vpype"], dict(os.environ), Path(tmp)))
            for case in cases:
                for version, env in versions.items():
                    runs.setdefault((case, version), []).append(
                        measure([sys.executable, "-m", "foldfab", *jobs[case]], env, Path(tmp)))
        floor = statistics.median(w for w, _, _ in yardstick)
        cpu_floor = statistics.median(c for _, c, _ in yardstick)
        print(f"yardstick `python -c \"import vpype\"`: {floor:.2f} s wall, {cpu_floor:.2f} s CPU "
              f"(median of {rounds})\n")
        print("| 1,001,000 faces | version | wall s | × import vpype | CPU s | × import vpype | peak MB |")
        print("|---|---|---:|---:|---:|---:|---:|")
        for (case, version), values in runs.items():
            wall, cpu, peak = (statistics.median(v[i] for v in values) for i in range(3))
            print(f"| {case} | {version} | {wall:.1f} | {wall / floor:.1f} | {cpu:.1f} | {cpu / cpu_floor:.1f} "
                  f"| {peak:.0f} |")


def base_option(args: list[str]) -> tuple[Path | None, list[str]]:
    """The folder of ``--base FOLDER`` in ``args`` (None without it), and the other arguments."""
    if "--base" not in args:
        return None, args
    at = args.index("--base")
    return Path(args[at + 1]).resolve(), args[:at] + args[at + 2:]


if __name__ == "__main__":
    base, args = base_option(sys.argv[1:])
    chosen = [a for a in args if not a.isdigit()] or ["design --fold", "export (optimize none)", "export"]
    main(int(next((a for a in args if a.isdigit()), 3)), base, chosen)
