"""Reflection-core speed: design build, penetration check, CLI summary, --help.

Run by hand:  python benchmarks/bench_design.py
Prints the best of several runs for each figure the README reports.
"""

from __future__ import annotations

import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from foldfab.geometry import templates
from foldfab.geometry.crease_pattern import build_crease_pattern
from foldfab.formats.mesh import to_trimesh
from foldfab.geometry.penetration import find_penetrations
from foldfab.geometry.reflection import reflect
from foldfab.geometry.split import auto_cuts, split_pattern

from warm_bytecode import cache_foldfab_bytecode


def wavy_design(profile_points: int, corners: int, radius: float = 40.0):
    """A regular column whose profile waves at 80% of the critical offset: valid, penetration-free."""
    w = 0.8 * radius * math.sin(math.pi / corners) * math.tan(math.pi / corners)
    v = np.linspace(0.0, 60.0, profile_points)
    profile = np.column_stack([w * np.sin(v / 60.0 * 6 * np.pi), v])
    return profile, templates.regular(corners, radius)


def best_of(fn, runs: int) -> float:
    best = math.inf
    for _ in range(runs):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def build(profile, trajectory):
    cp = build_crease_pattern(reflect(profile, trajectory), 1.0)
    to_trimesh(cp, weld=False)
    return cp


def main() -> None:
    rows = []
    for label, (j, n), runs in (("paper scale", (31, 36), 50), ("100,000 faces", (101, 1000), 10),
                                ("1,000,000 faces", (1001, 1000), 3)):
        profile, trajectory = wavy_design(j, n)
        cp = build(profile, trajectory)
        t = best_of(lambda: build(profile, trajectory), runs)
        rows.append((f"design build, {label} ({len(cp.faces):,} faces)", t))
    profile, trajectory = wavy_design(101, 1000)
    cp = build(profile, trajectory)
    rows.append((f"penetration check, {len(cp.faces):,} faces", best_of(lambda: find_penetrations(cp), 3)))
    grid = reflect(profile, trajectory)   # 251 x 60 mm, on pieces of at most 60 x 40 mm
    fits = lambda w, h: w <= 60 and h <= 40   # noqa: E731
    cuts = auto_cuts(grid, 0.0, fits)
    count = (len(cuts[0]) + 1) * (len(cuts[1]) + 1)
    rows.append((f"split auto, {len(cp.faces):,} faces (choose the cuts)", best_of(lambda: auto_cuts(grid, 0.0, fits), 3)))
    rows.append((f"split into {count} pieces, {len(cp.faces):,} faces (pieces and their marks)",
                 best_of(lambda: split_pattern(grid, 1.0, 0.0, *cuts), 3)))

    with tempfile.TemporaryDirectory() as tmp:
        job = Path(tmp) / "big.toml"
        points = ", ".join(f"[{u:.9f}, {v:.9f}]" for u, v in profile)
        job.write_text(f"[profile]\npoints = [{points}]\n[trajectory]\ntemplate = \"regular\"\ncorners = 1000\nradius = 40\n")
        cli = [sys.executable, "-m", "foldfab"]
        rows.append(("foldfab design (100,000 faces, summary, penetration check)",
                     best_of(lambda: subprocess.run(cli + ["design", str(job)], check=True, capture_output=True), 3)))
        rows.append(("foldfab --help", best_of(lambda: subprocess.run(cli + ["--help"], check=True, capture_output=True), 5)))
    width = max(len(r[0]) for r in rows)
    for name, seconds in rows:
        print(f"{name:<{width}}  {seconds * 1000:9.1f} ms")


if __name__ == "__main__":
    cache_foldfab_bytecode()
    main()
