"""The README's table of start-up and export figures, as ratios to a yardstick.

Run by hand:  python benchmarks/figures.py [ROUNDS] [--base FOLDER] [WORD ...]

This machine's speed drifts by 10-15% from one minute to the next, so each figure is the
median over ROUNDS (default 5) of a command run in turns with the yardstick,
``python -c "import vpype"`` (the floor of any foldfab command that fabricates), and is
given both as wall seconds and as CPU seconds (user + system: on a busy machine wall time
says more about the neighbours), each with its ratio to the yardstick's median of the same
rounds.  ``--base FOLDER`` also runs an unpacked other version of foldfab (``git archive
COMMIT | tar -x -C FOLDER``) in the same turns, for before/after figures; WORDs keep only the
commands whose label holds one of them (``paper``, ``help``).  Prints a Markdown table.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_fabrication import export_cases  # noqa: E402
from bench_scale import base_option, measure  # noqa: E402
from warm_bytecode import cache_foldfab_bytecode  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
FOLDFAB = [sys.executable, "-m", "foldfab"]
YARDSTICK = [sys.executable, "-c", "import vpype"]


def wall(command: list[str]) -> float:
    """Seconds the command takes; it must succeed."""
    start = time.perf_counter()
    subprocess.run(command, check=True, capture_output=True, cwd=ROOT)
    return time.perf_counter() - start


def main(rounds: int, base: Path | None, words: list[str]) -> None:
    versions = {"this": dict(os.environ)}
    cache_foldfab_bytecode(ROOT)
    if base is not None:
        versions[f"base ({base.name})"] = dict(os.environ, PYTHONPATH=str(base))
        cache_foldfab_bytecode(base)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        exports = dict(export_cases(tmp))
        cases = [
            ("`foldfab --help`", ["--help"]),
            ("`foldfab design jobs/hexagon-fig8a.toml` (summary)", ["design", str(ROOT / "jobs" / "hexagon-fig8a.toml")]),
            ("`foldfab export`, paper scale (1,000 faces, Graphtec)",
             ["export", *exports["paper scale: 1,000 faces from points"], "-o", str(tmp / "p.plt")]),
            ("`foldfab export`, 101,000 faces, 100,000 strokes (a 12.6 m roll)",
             ["export", *exports["101,000 faces, 100,000 strokes"], "-o", str(tmp / "r.plt")]),
        ]
        cases = [(label, argv) for label, argv in cases if not words or any(w in label for w in words)]
        runs: dict[tuple[str, str], list[tuple[float, float]]] = {}
        yardstick = []
        for _ in range(rounds):
            yardstick.append(measure(YARDSTICK, dict(os.environ), tmp)[:2])
            for label, argv in cases:
                for version, env in versions.items():
                    runs.setdefault((label, version), []).append(measure(FOLDFAB + argv, env, tmp)[:2])
        floor, cpu_floor = (statistics.median(y[i] for y in yardstick) for i in range(2))
        print(f"yardstick `python -c \"import vpype\"`: median {floor:.3f} s wall, {cpu_floor:.3f} s CPU "
              f"over {rounds} rounds\n")
        print("| what | version | wall | × `import vpype` | CPU | × `import vpype` |")
        print("|---|---|---:|---:|---:|---:|")
        for (label, version), values in runs.items():
            wall, cpu = (statistics.median(v[i] for v in values) for i in range(2))
            print(f"| {label} | {version} | {wall:.2f} s | {wall / floor:.2f} | {cpu:.2f} s | {cpu / cpu_floor:.2f} |")


if __name__ == "__main__":
    base, args = base_option(sys.argv[1:])
    main(int(next((a for a in args if a.isdigit()), 5)), base, [a for a in args if not a.isdigit()])
