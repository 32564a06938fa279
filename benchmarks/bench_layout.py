"""The design and lay-out stages of an export: CPU seconds of ``build_design`` and ``lay_out`` on a job.

Run by hand:  python benchmarks/bench_layout.py [ROUNDS] [--base FOLDER] [--job JOB --device DEVICE]

Default job: the export benchmark's 101,000-face roll (``bench_fabrication.export_cases``).
Each round runs one child process per version (this tree, and with ``--base FOLDER`` an
unpacked other version: ``git archive COMMIT | tar -x -C FOLDER``), in turns; a child imports
vpype first (its import is start-up, not these stages), then times each stage three times
and keeps the least CPU time.  Prints the median over ROUNDS (default 3) of each figure and
the child's peak resident memory (``wait4``'s ``ru_maxrss``, imports included).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

CHILD = """
import json, sys, time
import vpype  # noqa: F401
from foldfab.design import build_design
from foldfab.devices import load_device
from foldfab.fabrication.layout import lay_out, layer_tools, place
from foldfab.fabrication.spec import job_spec
from foldfab.job import load_job

job, device = load_job(sys.argv[1]), load_device(sys.argv[2])
design_s, layout_s = [], []
for _ in range(3):
    start = time.process_time()
    design = build_design(job)
    design_s.append(time.process_time() - start)
    spec = job_spec(design.job)
    start = time.process_time()
    placement, sheet = place(design, device, spec)
    lay_out(design, device, spec, placement, sheet, layer_tools(design, device, spec)[0])
    layout_s.append(time.process_time() - start)
print(json.dumps({"build_design": min(design_s), "lay_out": min(layout_s)}))
"""


def run(source: Path, job: str, device: str) -> dict[str, float]:
    """One child's figures, with ``source``'s foldfab first on the path."""
    env = {**os.environ, "PYTHONPATH": str(source)}
    child = subprocess.Popen([sys.executable, "-c", CHILD, job, device], stdout=subprocess.PIPE, env=env,
                             cwd=tempfile.gettempdir())
    out = child.stdout.read()
    _, status, usage = os.wait4(child.pid, 0)
    child.stdout.close()
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{source}: the child failed")
    return {**json.loads(out), "peak MB": usage.ru_maxrss / 1024}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("rounds", nargs="?", type=int, default=3)
    parser.add_argument("--base", type=Path, help="an unpacked other version of foldfab, run in the same turns")
    parser.add_argument("--job")
    parser.add_argument("--device")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        job, device = args.job, args.device
        if job is None:
            sys.path.insert(0, str(ROOT / "benchmarks"))
            from bench_fabrication import export_cases

            job, _, device = next(arguments for label, arguments in export_cases(Path(tmp)) if "100,000 strokes" in label)
        versions = {"this tree": ROOT} | ({"base": args.base.resolve()} if args.base else {})
        figures: dict[str, list[dict[str, float]]] = {name: [] for name in versions}
        for _ in range(args.rounds):
            for name, source in versions.items():
                figures[name].append(run(source, job, device))
        print(f"{Path(job).name} on {Path(device).name}, median of {args.rounds} rounds (CPU s; peak MB of the child)")
        for name, rounds in figures.items():
            median = {key: statistics.median(r[key] for r in rounds) for key in rounds[0]}
            print(f"  {name:10s} build_design {median['build_design']:.3f}  lay_out {median['lay_out']:.3f}  "
                  f"both {median['build_design'] + median['lay_out']:.3f}  peak {median['peak MB']:.0f} MB")


if __name__ == "__main__":
    main()
