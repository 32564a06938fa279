"""``foldfab print`` end to end: a paper-scale job and the 101,000-face job of the export
benchmark (bench_fabrication.export_cases), as PDF and as SVG pages, and where the time goes.

Run by hand:  python benchmarks/bench_print.py
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_fabrication import export_cases
from warm_bytecode import cache_foldfab_bytecode


def stages(job: Path) -> str:
    """CPU time of each stage in-process: design, layout, PDF rendering."""
    from foldfab.design import load_design
    from foldfab.printing.paper import PrintOptions
    from foldfab.printing.pdf import render_pdf
    from foldfab.printing.template import build_template

    start = time.process_time()
    design = load_design(job)
    built = time.process_time()
    template = build_template(design, PrintOptions())
    laid = time.process_time()
    render_pdf(template.pages, design.job.name)
    done = time.process_time()
    return f"design {built - start:.2f} s, layout {laid - built:.2f} s, PDF {done - laid:.2f} s"


def print_times() -> None:
    cli = [sys.executable, "-m", "foldfab", "print"]
    print("foldfab print on A4, end to end (best of 3; CPU time: the machine may be shared)")
    with tempfile.TemporaryDirectory() as tmp:
        cases = {label: args[0] for label, args in export_cases(Path(tmp))}
        for label in ("paper scale: 1,000 faces from points", "paper scale: jobs/vase-svg.toml (320 faces)",
                      "101,000 faces, 100,000 strokes"):
            job = Path(cases[label])
            for suffix in (".pdf", ".svg"):
                out = Path(tmp) / f"out{suffix}"
                best, cpu, info = float("inf"), float("inf"), {}
                for _ in range(3):
                    before = resource.getrusage(resource.RUSAGE_CHILDREN)
                    start = time.perf_counter()
                    result = subprocess.run(cli + [str(job), "-o", str(out), "--json"], check=True,
                                            capture_output=True, text=True)
                    best = min(best, time.perf_counter() - start)
                    after = resource.getrusage(resource.RUSAGE_CHILDREN)
                    cpu = min(cpu, after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime)
                    info = json.loads(result.stdout)
                size = sum(Path(p).stat().st_size for p in info["written"])
                print(f"{label:<45} {suffix} {best:6.2f} s wall {cpu:6.2f} s CPU   ({info['pages']} pages, {size:,} bytes)")
            print(f"{'':<45} in-process: {stages(job)}")


if __name__ == "__main__":
    cache_foldfab_bytecode()
    print_times()
