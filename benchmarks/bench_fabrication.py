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
from foldfab.programs.estimate import estimate, travel_times
from foldfab.fabricate import fabricate
from foldfab.fabrication.layout import build_plan, park_position
from foldfab.fabrication.spec import parse_fabrication
from foldfab.programs.interpret import interpret
from foldfab.fabrication.optimize import travel
from foldfab.fabrication.plan import PlotPlan

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


def closed(points) -> bool:
    """A stroke that ends where it starts, around at least three corners: it may start at any vertex."""
    import numpy as np

    return len(points) > 3 and bool(np.allclose(points[0], points[-1]))


def moves(ends, starts, motion):
    """Seconds [a, b] of a pen-up move from each point of ``ends`` (n, 2) to each of ``starts`` (m, 2)."""
    return travel_times(starts[None, :, :] - ends[:, None, :], motion)


def travel_floor(strokes, park: complex, device) -> float:
    """Seconds of pen-up travel that no order of these strokes within their layers can beat.

    Any plan is a path from the park position through every stroke and home again, so it
    pairs each stroke with the one drawn before it (or the park position), each with a
    different one, and the last with home: an assignment.  A move from stroke j to stroke
    i takes at least the quickest move between their candidate points (either end of an
    open stroke, any vertex of a closed one, which may start anywhere), each timed as the
    estimate times a pen-up move (:func:`~foldfab.programs.estimate.travel_times`); a stroke can only follow
    one of its own layer or of the layer before.  The cheapest assignment
    (``scipy.optimize.linear_sum_assignment``) is then a floor for every plan; it ignores
    that the pairs must form one path and that a stroke leaves from the other end than it
    entered, so it is not always reachable.
    """
    import numpy as np
    from scipy.optimize import linear_sum_assignment

    layers = {name: i for i, name in enumerate(dict.fromkeys(s.layer for s in strokes))}
    layer = np.array([layers[s.layer] for s in strokes] + [-1])  # the last row/column: park and home
    candidates = [s.points if closed(s.points)
                  else s.points[[0, -1]] for s in strokes] + [np.array([[park.real, park.imag]])]
    points = np.concatenate(candidates)
    starts = np.cumsum([0] + [len(c) for c in candidates[:-1]])
    cost = np.minimum.reduceat(np.minimum.reduceat(moves(points, points, device.motion), starts, axis=0),
                               starts, axis=1)  # [j, i]: from j to i
    last = layer[:-1].max()
    before, after = layer[:, None], layer[None, :]
    allowed = ((before == after) | (before == after - 1)) & (before >= 0) & (after >= 0)
    allowed[-1, :-1] = layer[:-1] == 0  # the first stroke comes from the park position
    allowed[:-1, -1] = layer[:-1] == last  # the last one goes home
    np.fill_diagonal(allowed, False)
    cost = np.where(allowed, cost, 1e9)
    rows, cols = linear_sum_assignment(cost)
    return float(cost[rows, cols].sum())


EXACT_STROKES = 18
"""Largest layer that :func:`optimal_travel` orders exactly (its work doubles per stroke)."""


def optimal_travel(strokes, park: complex, device) -> float | None:
    """Seconds of pen-up travel of the best order of these strokes (layers in order, each
    open stroke either way round, a closed one started at any vertex), or None when a layer
    has more than :data:`EXACT_STROKES` strokes.

    Held-Karp dynamic programming over the subsets of each layer, each stroke in both
    directions, carried from layer to layer by the cost of ending at each stroke end.
    """
    import numpy as np

    motion = device.motion

    def cost(ends, starts):  # [a, b]: seconds from end a to start b
        return moves(ends, starts, motion)

    ends, spent = np.array([[park.real, park.imag]]), np.zeros(1)  # where the pen may be, at what cost
    for name in dict.fromkeys(s.layer for s in strokes):
        lines = [s.points for s in strokes if s.layer == name]
        if len(lines) == 1 and closed(lines[0]):
            ring = lines[0][:-1]  # a closed stroke ends where it starts
            ends, spent = ring, (spent[:, None] + cost(ends, ring)).min(axis=0)
            continue
        if len(lines) > EXACT_STROKES:
            return None
        starts = np.array([p for line in lines for p in (line[0], line[-1])])  # state 2i + d
        finish = np.array([p for line in lines for p in (line[-1], line[0])])
        states, count = len(starts), len(lines)
        stroke = np.arange(states) // 2
        best = np.full((1 << count, states), np.inf)
        best[1 << stroke, np.arange(states)] = (spent[:, None] + cost(ends, starts)).min(axis=0)
        step = cost(finish, starts)
        for mask in range(1, 1 << count):
            reach = (best[mask][:, None] + step).min(axis=0)  # from any end state of mask to each start
            free = np.flatnonzero((mask >> stroke) & 1 == 0)
            target = mask | (1 << stroke[free])
            best[target, free] = np.minimum(best[target, free], reach[free])
        ends, spent = finish, best[-1]
    return float((spent + moves(ends, np.array([[park.real, park.imag]]), motion)[:, 0]).min())


def drawing_floor(run, device) -> float:
    """Seconds of drawing and pen lifts of these strokes, each closed one started at its
    sharpest corner: a loop started part-way along a straight edge splits that edge into
    two moves and pays one more stop, so no start a plan picks can do better."""
    import numpy as np

    strokes = []
    for stroke in run.strokes:
        if closed(stroke.points):
            ring = stroke.points[:-1]
            into, out = ring - np.roll(ring, 1, axis=0), np.roll(ring, -1, axis=0) - ring
            turn = np.abs(np.arctan2(into[:, 0] * out[:, 1] - into[:, 1] * out[:, 0], (into * out).sum(axis=1)))
            ring = np.roll(ring, -int(turn.argmax()), axis=0)
            stroke = dataclasses.replace(stroke, points=np.vstack([ring, ring[:1]]))
        strokes.append(stroke)
    corners = estimate(dataclasses.replace(run, strokes=strokes, travels=[]), device)
    return corners.draw_time + corners.lift_time


def over_floor(design, device, spec) -> tuple:
    """The estimate of ``design``'s plan, the share by which it exceeds the floor (see above),
    and by which it exceeds the best order of its strokes (None where that is not computed)."""
    fab = fabricate(design, device, spec)
    run = interpret(fab.program, device, fab.plan.sheet)
    est = estimate(run, device)
    park = park_position(device, fab.plan.sheet)
    floor = min(est.draw_time + est.lift_time, drawing_floor(run, device)) + travel_floor(run.strokes, park, device)
    best = optimal_travel(run.strokes, park, device)
    optimal = None if best is None else est.total - est.travel_time + best
    return est, 100 * (est.total / floor - 1), None if optimal is None else 100 * (est.total / optimal - 1)


def estimate_table(device_name: str = "graphtec-ce6000") -> None:
    device = load_device(device_name)
    print(f"\nestimated plot time on {device_name} vs the lower bound (drawn length at draw speed + "
          "unavoidable pen lifts), the floor of any order\nof the same strokes (their drawing time + lifts + "
          "unavoidable travel) and their best order (exact, for layers of up to 18 strokes)")
    for name in JOBS:
        design = load_design(ROOT / "jobs" / f"{name}.toml")
        spec = parse_fabrication({"sheet": "A3", "margin": 5, "scale": 0.5}, name)
        est, floor, optimal = over_floor(design, device, spec)
        unsorted = over_floor(design, device, dataclasses.replace(spec, optimize="none"))[1]
        ramps = est.draw_time + est.lift_time - est.lower_bound  # acceleration at stroke ends and corners
        best = "  (too large)" if optimal is None else f"  best order +{optimal:3.1f}%"
        print(f"{name:<17} estimate {est.total:6.1f} s, bound {est.lower_bound:6.1f} s "
              f"+{100 * (est.total / est.lower_bound - 1):4.1f}% (travel {est.travel_time:4.1f} s, "
              f"ramps {ramps:4.1f} s); floor +{floor:3.1f}% (unsorted +{unsorted:4.1f}%){best}")


def export_cases(tmp: Path) -> list[tuple[str, list[str]]]:
    """The export benchmark's jobs, written into ``tmp``: (label, ``foldfab export`` arguments
    without ``-o``).  Shared with ``figures.py``."""
    big = tmp / "big.toml"  # a zigzag profile of 1,001 points x 100 corners: 101,000 faces, 12.6 m
    points = ", ".join(f"[{0.03 * (i % 2)}, {0.05 * i:.2f}]" for i in range(1001))
    big.write_text(f"[profile]\npoints = [{points}]\n[trajectory]\ntemplate = \"regular\"\ncorners = 100\n"
                   "radius = 2000\n[fabrication]\nsheet = [13000, 100]\nmargin = 5\n")
    smooth = tmp / "smooth.toml"  # a smooth profile: 101,000 faces, but its profile creases are flat
    points = ", ".join(f"[{1 + 0.8 * math.sin(i / 80):.4f}, {0.1 * i:.2f}]" for i in range(1001))
    smooth.write_text(f"[profile]\npoints = [{points}]\n[trajectory]\ntemplate = \"regular\"\ncorners = 100\n"
                      "radius = 2000\n[fabrication]\nsheet = [13000, 200]\nmargin = 5\n")
    paper = tmp / "paper.toml"  # 41 profile points x 24 corners: 1,000 faces
    points = ", ".join(f"[{i % 2}, {4 * i}]" for i in range(41))
    paper.write_text(f"[profile]\npoints = [{points}]\n[trajectory]\ntemplate = \"regular\"\ncorners = 24\n"
                     "radius = 60\n[fabrication]\nsheet = \"A3\"\nmargin = 5\nscale = 0.5\n")
    vase = ROOT / "jobs" / "vase-svg.toml"
    (tmp / "vase.toml").write_text(vase.read_text().replace('"vase-profile.svg"', f'"{ROOT / "jobs" / "vase-profile.svg"}"')
                                   .replace('scale = "fit"', 'sheet = "A3"\nmargin = 5\nscale = 0.7'))
    profile = (ROOT / "devices" / "graphtec-ce6000.toml").read_text()
    (tmp / "long.toml").write_text(profile.replace('name = "graphtec-ce6000"', 'name = "long-roll"')
                                   .replace("plottable_area = [1000, 375]", "plottable_area = [375, 13000]"))
    profile = (ROOT / "devices" / "grbl.toml").read_text()
    (tmp / "grbl-roll.toml").write_text(profile.replace('name = "grbl"', 'name = "grbl-roll"')
                                        .replace("plottable_area = [300, 300]", "plottable_area = [13000, 375]"))
    return [("paper scale: 1,000 faces from points", [str(paper), "--device", "graphtec-ce6000"]),
            ("paper scale: jobs/vase-svg.toml (320 faces)", [str(tmp / "vase.toml"), "--device", "graphtec-ce6000"]),
            ("101,000 faces, 100,000 strokes", [str(big), "--device", str(tmp / "long.toml")]),
            ("the same as G-code (GRBL)", [str(big), "--device", str(tmp / "grbl-roll.toml")]),
            ("101,000 faces, smooth profile: 101 strokes", [str(smooth), "--device", str(tmp / "long.toml")])]


def export_times() -> None:
    cli = [sys.executable, "-m", "foldfab", "export"]
    print("\nfoldfab export, end to end (best of 3)")
    with tempfile.TemporaryDirectory() as tmp:
        for label, args in export_cases(Path(tmp)):
            out = Path(tmp) / ("out.gcode" if "grbl" in args[-1] else "out.plt")
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
