"""``foldfab print``: the pieces and pages of every example job on A4, and the time of a
print end to end for a paper-scale job and for the 101,000-face job of the export benchmark
(bench_fabrication.export_cases), as wall seconds and as a ratio to ``python -c "import
vpype"`` run in turns with them (figures.py's yardstick: this machine's speed drifts from one
minute to the next), with where the time of each goes in-process.

Run by hand:  python benchmarks/bench_print.py [ROUNDS]
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_fabrication import export_cases  # noqa: E402
from figures import FOLDFAB, ROOT, YARDSTICK, wall  # noqa: E402
from warm_bytecode import cache_foldfab_bytecode  # noqa: E402

CASES = ("paper scale: 1,000 faces from points", "101,000 faces, 100,000 strokes")
"""The export benchmark's jobs printed here: a paper-scale one and the 101,000-face roll."""


def stages(job: Path) -> str:
    """CPU time of each stage in-process: design, pieces, layout, PDF rendering."""
    from foldfab.design import load_design
    from foldfab.printing.output import template_pieces
    from foldfab.printing.paper import PrintOptions
    from foldfab.printing.pdf import render_pdf
    from foldfab.printing.template import build_template

    start = time.process_time()
    design = load_design(job)
    built = time.process_time()
    pieces = template_pieces(design, PrintOptions())
    cut = time.process_time()
    template = build_template(design, PrintOptions(), pieces)
    laid = time.process_time()
    render_pdf(template.pages, design.job.name)
    done = time.process_time()
    return (f"design {built - start:.2f} s, pieces {cut - built:.2f} s, layout {laid - cut:.2f} s, "
            f"PDF {done - laid:.2f} s")


def print_info(job: Path, out: Path) -> dict:
    """``foldfab print --json`` of ``job`` on A4."""
    result = subprocess.run(FOLDFAB + ["print", str(job), "-o", str(out), "--json"], check=True,
                            capture_output=True, text=True, cwd=ROOT)
    return json.loads(result.stdout)


def pieces_and_pages(tmp: Path) -> None:
    """Every example job printed on A4: pieces, pages (the first page included) and tiles."""
    print("| job | pieces | A4 pages | tiles (rows x columns) per piece |")
    print("|---|---:|---:|---|")
    for job in sorted((ROOT / "jobs").glob("*.toml")):
        info = print_info(job, tmp / "job.pdf")
        tiles = ", ".join(f"{rows} x {cols}" for rows, cols in info["tiles"])
        print(f"| `{job.stem}` | {info['pieces']} | {info['pages']} | {tiles} |")


def print_times(tmp: Path, rounds: int) -> None:
    """The two jobs printed in turns with the yardstick: medians and ratios."""
    jobs = dict(export_cases(tmp))
    commands = {label: FOLDFAB + ["print", jobs[label][0], "-o", str(tmp / "t.pdf")] for label in CASES}
    pages = {label: print_info(Path(jobs[label][0]), tmp / "t.pdf")["pages"] for label in CASES}
    times: dict[str, list[float]] = {label: [] for label in CASES}
    yardstick = []
    for _ in range(rounds):
        yardstick.append(wall(YARDSTICK))
        for label, command in commands.items():
            times[label].append(wall(command))
    floor = statistics.median(yardstick)
    print(f"\nyardstick `python -c \"import vpype\"`: median {floor:.3f} s over {rounds} rounds, in turns\n")
    print("| `foldfab print` (PDF, A4) | pages | median | × `import vpype` |")
    print("|---|---:|---:|---:|")
    for label in CASES:
        median = statistics.median(times[label])
        print(f"| {label} | {pages[label]} | {median:.2f} s | {median / floor:.2f} |")
    for label in CASES:
        print(f"\n{label}, in-process CPU: {stages(Path(jobs[label][0]))}")


def main(rounds: int) -> None:
    cache_foldfab_bytecode()
    with tempfile.TemporaryDirectory() as tmp:
        pieces_and_pages(Path(tmp))
        print_times(Path(tmp), rounds)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 5)
