"""The README's table of start-up and export figures, as ratios to a yardstick.

Run by hand:  python benchmarks/figures.py [ROUNDS]

This machine's speed drifts by 10-15% from one minute to the next, so each figure is the
median over ROUNDS (default 5) of a command run in turns with the yardstick,
``python -c "import vpype"`` (the floor of any foldfab command that fabricates), and is
given both as wall seconds and as a ratio to the yardstick's median of the same rounds.
Prints a Markdown table.
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_fabrication import export_cases  # noqa: E402
from warm_bytecode import cache_foldfab_bytecode  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
FOLDFAB = [sys.executable, "-m", "foldfab"]
YARDSTICK = [sys.executable, "-c", "import vpype"]


def wall(command: list[str]) -> float:
    """Seconds the command takes; it must succeed."""
    start = time.perf_counter()
    subprocess.run(command, check=True, capture_output=True, cwd=ROOT)
    return time.perf_counter() - start


def main(rounds: int) -> None:
    cache_foldfab_bytecode()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        exports = dict(export_cases(tmp))
        cases = [
            ("`foldfab --help`", FOLDFAB + ["--help"]),
            ("`foldfab design jobs/hexagon-fig8a.toml` (summary)", FOLDFAB + ["design", "jobs/hexagon-fig8a.toml"]),
            ("`foldfab export`, paper scale (1,000 faces, Graphtec)",
             FOLDFAB + ["export", *exports["paper scale: 1,000 faces from points"], "-o", str(tmp / "p.plt")]),
            ("`foldfab export`, 101,000 faces, 100,000 strokes (a 12.6 m roll)",
             FOLDFAB + ["export", *exports["101,000 faces, 100,000 strokes"], "-o", str(tmp / "r.plt")]),
        ]
        times: dict[str, list[float]] = {label: [] for label, _ in cases}
        yardstick = []
        for _ in range(rounds):
            yardstick.append(wall(YARDSTICK))
            for label, command in cases:
                times[label].append(wall(command))
        floor = statistics.median(yardstick)
        print(f"yardstick `python -c \"import vpype\"`: median {floor:.3f} s over {rounds} rounds\n")
        print("| what | median | × `import vpype` |")
        print("|---|---:|---:|")
        for label, _ in cases:
            median = statistics.median(times[label])
            print(f"| {label} | {median:.2f} s | {median / floor:.2f} |")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 5)
