"""Fabrication quality and speed: pen-up travel, time estimate vs lower bound, export time.

Run by hand:  python benchmarks/bench_fabrication.py
"""

from __future__ import annotations

import dataclasses
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path


from foldfab.design import load_design
from foldfab.devices import load_device
from foldfab.estimate import estimate
from foldfab.fabrication import build_plan, fabricate, parse_fabrication, park_position
from foldfab.interpret import interpret
from foldfab.optimize import travel
from foldfab.plan import PlotPlan

from warm_bytecode import cache_foldfab_bytecode

ROOT = Path(__file__).resolve().parent.parent
JOBS = ["hexagon-fig8a", "diamond-fig9", "vase-svg", "star", "open-wave-fig11f", "helix-fig12"]


def vpype_plain(plan: PlotPlan) -> PlotPlan:
    """The same layers through vpype's plain ``linemerge linesort`` pipeline."""
    import vpype_cli

    return PlotPlan(vpype_cli.execute("linemerge linesort", plan.document), plan.steps, plan.sheet)


def travel_table(device_name: str = "graphtec-ce6000") -> None:
    device = load_device(device_name)
    print(f"pen-up travel on {device_name}, mm (A3, scale 0.5, force strategy; all layers, park and between layers)")
    print(f"{'job':<18}{'unsorted':>10}{'vpype linemerge linesort':>26}{'foldfab greedy':>16}{'foldfab two-opt':>17}")
    for name in JOBS:
        design = load_design(ROOT / "jobs" / f"{name}.toml")
        spec = parse_fabrication({"sheet": "A3", "margin": 5, "scale": 0.5}, name)
        park = park_position(device, spec.sheet)
        raw = build_plan(design, device, dataclasses.replace(spec, optimize="none"))
        figures = [travel(raw, park)["total"], travel(vpype_plain(raw), park)["total"],
                   travel(build_plan(design, device, spec), park)["total"],
                   travel(build_plan(design, device, dataclasses.replace(spec, optimize="two-opt")), park)["total"]]
        print(f"{name:<18}" + "".join(f"{v:>{w}.0f}" for v, w in zip(figures, (10, 26, 16, 17))))


def estimate_table(device_name: str = "graphtec-ce6000") -> None:
    device = load_device(device_name)
    print(f"\nestimated plot time vs lower bound on {device_name} (drawn length at draw speed + unavoidable pen lifts)")
    for name in JOBS:
        design = load_design(ROOT / "jobs" / f"{name}.toml")
        fab = fabricate(design, device, parse_fabrication({"sheet": "A3", "margin": 5, "scale": 0.5}, name))
        est = estimate(interpret(fab.program, device, fab.plan.sheet), device)
        ramps = est.draw_time + est.lift_time - est.lower_bound  # acceleration at stroke ends and corners
        print(f"{name:<18} estimate {est.total:7.1f} s   lower bound {est.lower_bound:7.1f} s   "
              f"+{100 * (est.total / est.lower_bound - 1):5.1f}%   of the gap: pen-up travel "
              f"{est.travel_time:5.1f} s, drawing ramps {ramps:5.1f} s")


def export_times() -> None:
    cli = [sys.executable, "-m", "foldfab", "export"]
    print("\nfoldfab export, end to end (best of 3)")
    with tempfile.TemporaryDirectory() as tmp:
        big = Path(tmp) / "big.toml"  # a zigzag profile of 1,001 points x 100 corners: 101,000 faces, 12.6 m
        points = ", ".join(f"[{0.03 * (i % 2)}, {0.05 * i:.2f}]" for i in range(1001))
        big.write_text(f"[profile]\npoints = [{points}]\n[trajectory]\ntemplate = \"regular\"\ncorners = 100\n"
                       "radius = 2000\n[fabrication]\nsheet = [13000, 100]\nmargin = 5\n")
        smooth = Path(tmp) / "smooth.toml"  # a smooth profile: 101,000 faces, but its profile creases are flat
        points = ", ".join(f"[{1 + 0.8 * math.sin(i / 80):.4f}, {0.1 * i:.2f}]" for i in range(1001))
        smooth.write_text(f"[profile]\npoints = [{points}]\n[trajectory]\ntemplate = \"regular\"\ncorners = 100\n"
                          "radius = 2000\n[fabrication]\nsheet = [13000, 200]\nmargin = 5\n")
        paper = Path(tmp) / "paper.toml"  # 41 profile points x 24 corners: 1,000 faces
        points = ", ".join(f"[{i % 2}, {4 * i}]" for i in range(41))
        paper.write_text(f"[profile]\npoints = [{points}]\n[trajectory]\ntemplate = \"regular\"\ncorners = 24\n"
                         "radius = 60\n[fabrication]\nsheet = \"A3\"\nmargin = 5\nscale = 0.5\n")
        cases = [("paper scale: 1,000 faces from points", [str(paper), "--device", "graphtec-ce6000"]),
                 ("paper scale: jobs/vase-svg.toml (320 faces)", [str(ROOT / "jobs" / "vase-svg.toml"), "--device", "graphtec-ce6000"]),
                 ("101,000 faces, 100,000 strokes", [str(big), "--device", str(Path(tmp) / "long.toml")]),
                 ("the same as G-code (GRBL)", [str(big), "--device", str(Path(tmp) / "grbl-roll.toml")]),
                 ("101,000 faces, smooth profile: 101 strokes", [str(smooth), "--device", str(Path(tmp) / "long.toml")])]
        profile = (ROOT / "devices" / "graphtec-ce6000.toml").read_text()
        (Path(tmp) / "long.toml").write_text(profile.replace('name = "graphtec-ce6000"', 'name = "long-roll"')
                                             .replace("plottable_area = [1000, 375]", "plottable_area = [375, 13000]"))
        profile = (ROOT / "devices" / "grbl.toml").read_text()
        (Path(tmp) / "grbl-roll.toml").write_text(profile.replace('name = "grbl"', 'name = "grbl-roll"')
                                                  .replace("plottable_area = [300, 300]", "plottable_area = [13000, 375]"))
        vase = ROOT / "jobs" / "vase-svg.toml"
        for label, args in cases:
            out = Path(tmp) / ("out.gcode" if "grbl" in args[-1] else "out.plt")
            if args[0] == str(vase):
                job = Path(tmp) / "vase.toml"
                job.write_text(vase.read_text().replace('"vase-profile.svg"', f'"{ROOT / "jobs" / "vase-profile.svg"}"')
                               + "\n[fabrication]\nsheet = \"A3\"\nmargin = 5\nscale = 0.7\n")
                args = [str(job)] + args[1:]
            best = math.inf
            for _ in range(3):
                start = time.perf_counter()
                subprocess.run(cli + args + ["-o", str(out)], check=True, capture_output=True)
                best = min(best, time.perf_counter() - start)
            faces = subprocess.run([sys.executable, "-m", "foldfab", "design", args[0]], check=True,
                                   capture_output=True, text=True).stdout.split("faces ")[1].split(",")[0]
            print(f"{label:<45} {best:6.2f} s   ({faces} faces, {out.stat().st_size:,} bytes)")


if __name__ == "__main__":
    cache_foldfab_bytecode()
    travel_table()
    estimate_table()
    estimate_table("grbl")
    export_times()
