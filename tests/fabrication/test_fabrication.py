"""Fabrication end to end: job -> plan -> program -> interpreter gives back exactly the creases and outline."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from foldfab.design import load_design
from foldfab.devices import load_device
from foldfab.errors import FoldfabError
from foldfab.programs.estimate import estimate
from foldfab.fabricate import fabricate
from foldfab.fabrication.layout import finish_plan
from foldfab.fabrication.spec import parse_fabrication
from foldfab.programs.interpret import interpret
from foldfab.programs.languages import write_program
from foldfab.fabrication.scoring import _chains, crease_lines, outline_loops
from helpers import DEVICES, JOBS, ROOT
from helpers.plans import spec, whole



def crease_segments(cp, kind: str) -> np.ndarray:
    """The crease pattern's own edges of ``kind`` as (S, 2) complex end points: the oracle."""
    p = cp.vertices[cp.edges[cp.assignment == kind]]
    return p[..., 0] + 1j * p[..., 1]


@pytest.mark.parametrize("job", sorted((ROOT / "jobs").glob("*.toml")), ids=lambda p: p.stem)
def test_chained_creases_and_outline_cover_every_edge_once(job):
    cp = load_design(job).crease_pattern

    def pairs(segments) -> list:
        return sorted(tuple(sorted([(a.real, a.imag), (b.real, b.imag)])) for a, b in segments)
    for kind in "MV":
        lines = crease_lines(cp, kind)
        walked = [(line[i], line[i + 1]) for line in lines for i in range(len(line) - 1)]
        assert pairs(walked) == pairs(crease_segments(cp, kind))
        assert len(lines) <= len(crease_segments(cp, kind))
    loops = outline_loops(cp)
    assert all(loop[0] == loop[-1] for loop in loops)
    walked = [(loop[i], loop[i + 1]) for loop in loops for i in range(len(loop) - 1)]
    assert pairs(walked) == pairs(crease_segments(cp, "B"))


def _components(edges: list[tuple[int, int]]) -> dict[int, list[tuple[int, int]]]:
    """Edges by connected component (union-find), keyed by a root vertex."""
    root: dict[int, int] = {}

    def find(v: int) -> int:
        while root.setdefault(v, v) != v:
            v = root[v]
        return v
    for a, b in edges:
        root[find(a)] = find(b)
    groups: dict[int, list[tuple[int, int]]] = {}
    for a, b in edges:
        groups.setdefault(find(a), []).append((a, b))
    return groups


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 11), st.integers(0, 11)).filter(lambda e: e[0] != e[1]), max_size=40),
       st.booleans())
def test_chains_walk_every_edge_once_with_the_fewest_strokes(edges, collinear):
    """Euler: a connected set of edges with 2k odd vertices takes k strokes (one loop if k is 0)."""
    # distinct points, on one line (every turn is straight on or a reversal) or on a spiral
    points = np.arange(12) * (1 + 0.37j) if collinear else (np.arange(12) + 1) * np.exp(2.4j * np.arange(12))
    name = {complex(p): i for i, p in enumerate(points)}
    lines = _chains(np.array(edges, dtype=np.intp).reshape(-1, 2), points)
    walked = sorted(tuple(sorted((name[complex(a)], name[complex(b)])))
                    for line in lines for a, b in zip(line[:-1], line[1:]))
    assert walked == sorted(tuple(sorted(e)) for e in edges)
    fewest = 0
    for group in _components(edges).values():
        odd = np.count_nonzero(np.bincount(np.ravel(group), minlength=12) % 2)
        fewest += max(1, odd // 2)
    assert len(lines) == fewest


def _straight_strokes(lines: list[np.ndarray]) -> bool:
    """Whether every stroke goes straight on at each of its points."""
    for line in lines:
        steps = np.diff(line)
        if np.any(np.abs((steps[1:] * steps[:-1].conj()).imag) > 1e-9 * np.abs(steps[1:] * steps[:-1])) \
                or np.any((steps[1:] * steps[:-1].conj()).real <= 0):
            return False
    return True


@settings(max_examples=100, deadline=None)
@given(st.lists(st.integers(0, 10), min_size=1, max_size=5, unique=True),
       st.lists(st.integers(0, 10), min_size=1, max_size=5, unique=True),
       st.floats(0.3, 2.8), st.floats(0, 6.3), st.randoms(use_true_random=False))
def test_chains_draw_crossing_lines_straight_through(rows, columns, crossing, turn, rng):
    """Lines that cross (two families at an angle, edges numbered at random) come back as
    the lines themselves: one straight stroke each, never a turn at a crossing."""
    across, along = np.exp(1j * turn), np.exp(1j * (turn + crossing))  # point (a, b): a across + b along
    index: dict[tuple[int, int], int] = {}
    points: list[complex] = []

    def vertex(a: int, b: int) -> int:
        if (a, b) not in index:
            index[a, b] = len(points)
            points.append(a * across + b * along)
        return index[a, b]
    edges = []
    for b in rows:  # a line along "across" at b, from a = -1 to 11, through every column
        stops = [-1] + sorted(columns) + [11]
        edges += [(vertex(p, b), vertex(q, b)) for p, q in zip(stops[:-1], stops[1:])]
    for a in columns:
        stops = [-1] + sorted(rows) + [11]
        edges += [(vertex(a, p), vertex(a, q)) for p, q in zip(stops[:-1], stops[1:])]
    rng.shuffle(edges)
    edges = [e if rng.random() < 0.5 else e[::-1] for e in edges]
    lines = _chains(np.array(edges, dtype=np.intp), np.array(points))
    assert len(lines) == len(rows) + len(columns)
    assert _straight_strokes(lines)
    assert sorted(len(line) for line in lines) == sorted([len(columns) + 2] * len(rows) + [len(rows) + 2] * len(columns))


@settings(max_examples=100, deadline=None)
@given(st.lists(st.integers(0, 30), min_size=1, max_size=6, unique=True), st.randoms(use_true_random=False))
def test_chains_pair_the_straightest_edges_at_a_vertex(angles, rng):
    """Lines through one point at distinct angles: each is drawn straight through it."""
    ends = [r * np.exp(0.1j * t) for t in angles for r in (1, -1)]
    rng.shuffle(ends)  # numbered at random
    points = [0j] + ends
    edges = [(0, k) for k in range(1, len(points))]
    lines = _chains(np.array(edges, dtype=np.intp), np.array(points))
    assert len(lines) == len(angles)
    assert _straight_strokes(lines)


def _dist_to_segments(points: np.ndarray, segs: np.ndarray) -> np.ndarray:
    """Distance of each complex point to the nearest of the (S, 2) complex segments."""
    a, b = segs[:, 0][None, :], segs[:, 1][None, :]
    d = b - a
    t = np.clip(((points[:, None] - a) * np.conj(d)).real / np.maximum(np.abs(d) ** 2, 1e-30), 0, 1)
    return np.abs(points[:, None] - (a + t * d)).min(axis=1)


def _samples(segs: np.ndarray, n: int = 7) -> np.ndarray:
    t = np.linspace(0, 1, n)
    return (segs[:, :1] + (segs[:, 1:] - segs[:, :1]) * t[None, :]).ravel()


def stroke_segments(run, layer: str) -> np.ndarray:
    segs = [np.column_stack([s.points[:-1, 0] + 1j * s.points[:-1, 1], s.points[1:, 0] + 1j * s.points[1:, 1]])
            for s in run.strokes if s.layer == layer and len(s.points) > 1]
    return np.concatenate(segs) if segs else np.zeros((0, 2), complex)


def expected_segments(design, placement, layer: str) -> np.ndarray:
    cp = design.crease_pattern
    if layer == "cut":
        segs = np.concatenate([np.column_stack([loop[:-1], loop[1:]]) for loop in outline_loops(cp)])
    else:
        segs = crease_segments(cp, {"valley": "V", "mountain": "M"}[layer])
    return placement.apply(segs)


@pytest.mark.parametrize("device_name", DEVICES)
@pytest.mark.parametrize("job", JOBS, ids=[j.stem for j in JOBS])
def test_round_trip_every_job_every_device(job, device_name):
    """Every non-flat crease and the outline come back on their layer within one plotter unit, nothing else."""
    design = load_design(job)
    device = load_device(device_name)
    fab = fabricate(design, device, spec(**whole(design)))
    run = interpret(fab.program, device, fab.plan.sheet)
    tol = 1.5 * device.resolution + 1e-9  # rounding + simplification bound (one unit: 0.001 mm in G-code)
    for layer in ("valley", "mountain", "cut"):
        want = expected_segments(design, fab.placement, layer)
        got = stroke_segments(run, layer)
        if len(want) == 0:
            assert len(got) == 0
            continue
        assert _dist_to_segments(_samples(want), got).max() <= tol, f"{layer}: a crease is missing"
        assert _dist_to_segments(_samples(got), want).max() <= tol, f"{layer}: something extra is drawn"
    # flat creases are never scored, the outline is cut last as closed loops
    assert [s.layer for s in run.strokes][-1] == "cut"
    cut = [s for s in run.strokes if s.layer == "cut"]
    assert all(np.allclose(s.points[0], s.points[-1], atol=tol) for s in cut)
    names = [s.layer for s in run.strokes]
    assert names == sorted(names, key=["valley", "mountain", "cut"].index), "layers were reordered"


@pytest.mark.parametrize("device_name", DEVICES)
def test_output_is_deterministic(device_name):
    device = load_device(device_name)
    design = load_design(ROOT / "jobs" / "vase-svg.toml")
    a = fabricate(design, device, spec(strategy="two-sided")).program.text
    b = fabricate(load_design(ROOT / "jobs" / "vase-svg.toml"), device, spec(strategy="two-sided")).program.text
    assert a == b


def test_perforation_duty_cycle_and_clearance():
    design = load_design(ROOT / "jobs" / "hexagon-fig8a.toml")
    device = load_device("graphtec-ce6000")
    fab = fabricate(design, device, spec(strategy="perforate", scale=1.0, sheet="A3 landscape"))
    run = interpret(fab.program, device, fab.plan.sheet)
    for layer, pattern in (("valley", (1.0, 1.0)), ("mountain", (2.0, 1.0, 0.5, 1.0))):
        duty = sum(pattern[0::2]) / sum(pattern)
        creases = expected_segments(design, fab.placement, layer)
        dashes = stroke_segments(run, layer)
        dash_len = np.abs(dashes[:, 1] - dashes[:, 0])
        assert dash_len.max() <= max(pattern[0::2]) + 0.05
        for seg in creases:
            length = abs(seg[1] - seg[0])
            usable = length - 2 * 1.0
            if usable < 10 * sum(pattern):
                continue
            on = _dist_to_segments(np.concatenate([dashes[:, 0], dashes[:, 1]]), seg[None, :]) < 0.03
            mine = on.reshape(2, -1).all(axis=0)
            cut = dash_len[mine].sum()
            assert abs(cut / usable - duty) <= sum(pattern) / usable + 0.01
            # nothing within the clearance of the crease's ends
            ends = np.concatenate([dashes[mine, 0], dashes[mine, 1]])
            assert np.abs(ends[:, None] - seg[None, :]).min() >= 1.0 - 0.03


def test_two_sided_mountains_are_the_exact_mirror():
    design = load_design(ROOT / "jobs" / "star.toml")
    device = load_device("graphtec-ce6000")
    fab = fabricate(design, device, spec(strategy="two-sided", scale=0.6))
    run = interpret(fab.program, device, fab.plan.sheet)
    assert len(run.pauses) == 1 and "Flip the sheet" in run.pauses[0].message
    width = fab.plan.sheet[0]
    front = fab.placement.apply(crease_segments(design.crease_pattern, "M"))
    back = stroke_segments(run, "mountain")
    unmirrored = (width - back.real) + 1j * back.imag
    tol = 1.5 * device.resolution + 1e-9
    assert _dist_to_segments(_samples(front), unmirrored).max() <= tol
    assert _dist_to_segments(_samples(unmirrored), front).max() <= tol
    # valleys stay on the front, unmirrored
    assert _dist_to_segments(_samples(fab.placement.apply(crease_segments(design.crease_pattern, "V"))),
                             stroke_segments(run, "valley")).max() <= tol
    # the pause comes after every valley and before any mountain
    assert run.pauses[0].strokes_before == sum(s.layer == "valley" for s in run.strokes)


def test_optimization_reduces_travel_and_reports_every_part():
    design = load_design(ROOT / "jobs" / "vase-svg.toml")
    fab = fabricate(design, load_device("roland-gx24"), spec())
    assert fab.travel_after["total"] < 0.5 * fab.travel_before["total"]
    assert {"from park", "valley", "mountain", "cut", "between layers", "to park"} <= set(fab.travel_after["layers"])
    assert fab.travel_after["total"] == pytest.approx(sum(fab.travel_after["layers"].values()))


def test_design_too_big_names_sizes_and_largest_scale():
    """The message states both sizes and the largest scale; that scale fits, a hair more does not."""
    import re

    design = load_design(ROOT / "jobs" / "vase-svg.toml")
    device = load_device("hp7475a")
    with pytest.raises(FoldfabError) as info:
        fabricate(design, device, spec(sheet="A4", scale=1.0))
    message = str(info.value)
    assert re.search(r"the design is 371\.4 x 73\.9 mm at scale 1, but only [\d.]+ x [\d.]+ mm is usable", message)
    assert "sheet 210 x 297 mm" in message
    largest = float(re.search(r"largest scale that fits is ([\d.]+)", message).group(1))
    fab = fabricate(design, device, spec(sheet="A4", scale=largest))
    lo, hi = fab.plan.document.bounds()[:2], fab.plan.document.bounds()[2:]
    x0, y0, x1, y1 = device.frame(fab.plan.sheet).device_rect_on_sheet(*device.plottable_area)
    assert lo[0] >= max(5, x0) - 1e-6 and lo[1] >= max(5, y0) - 1e-6
    assert hi[0] <= min(205, x1) + 1e-6 and hi[1] <= min(292, y1) + 1e-6
    with pytest.raises(FoldfabError, match="largest scale"):
        fabricate(design, device, spec(sheet="A4", scale=largest * 1.001))


@pytest.mark.parametrize("device_name", DEVICES)
def test_a_design_scaled_below_ten_plotter_steps_is_refused(device_name):
    """A mistyped scale would stab the tool at one point; the error gives the size it came to."""
    design = load_design(ROOT / "jobs" / "hexagon-fig8a.toml")
    device = load_device(device_name)
    width, height = np.ptp(design.crease_pattern.vertices, axis=0)
    smallest = 10 * device.resolution / min(width, height)
    with pytest.raises(FoldfabError, match=rf"mm at scale {smallest / 2:g}, under 10 of the device's steps "
                                           rf"\({device.resolution:g} mm\) across.*larger \[fabrication\]\.scale"):
        fabricate(design, device, spec(scale=smallest / 2))
    fabricate(design, device, spec(scale=smallest * 1.01))


@pytest.mark.parametrize("table, message", [
    ({"strategy": "laser"}, r"\[fabrication\]\.strategy: expected one of"),
    ({"sheet": "B5"}, r"\[fabrication\]\.sheet: expected"),
    ({"scale": 0}, r"\[fabrication\]\.scale: must be greater than 0"),
    ({"optimize": "best"}, r"\[fabrication\]\.optimize"),
    ({"perforate": {"valley": [1, 1, 1]}}, r"\[fabrication\.perforate\]\.valley: expected an even-length list"),
    ({"perforate": {"valley": [1e-9, 1e-9]}}, r"\.valley: expected .* lengths from 0\.1 to 1000 mm, got \[1e-09"),
    ({"perforate": {"mountain": [1, float("inf")]}}, r"\.mountain: expected .* from 0\.1 to 1000 mm, got \[1, inf\]"),
    ({"perforate": {"valley": [0.05, 1]}}, r"\.valley: expected .* from 0\.1"),
    ({"layers": {"fold": {}}}, r"\[fabrication\.layers\]\.fold: unknown key; expected one of: cut, mountain, valley$"),
    ({"perforation": {}}, r"\[fabrication\]\.perforation: unknown key; did you mean 'perforate'\? expected one of: flip_edge, "
                          r"layers, margin, max_strokes, media, optimize, perforate, rotate, scale, sheet, split, split_height, strategy$"),
    ({"perforate": {"gap": 1}}, r"\[fabrication\.perforate\]\.gap: unknown key; expected one of: clearance, "
                                r"mountain, valley$"),
    ({"colour": "red"}, r"\[fabrication\]\.colour: unknown key"),
])
def test_bad_fabrication_tables(table, message):
    with pytest.raises(FoldfabError, match=message):
        parse_fabrication(table, "job.toml")


def test_layer_override_reaches_the_program():
    design = load_design(ROOT / "jobs" / "hexagon-fig8a.toml")
    device = load_device("graphtec-ce6000")
    fab = fabricate(design, device, spec(layers={"cut": {"force": 30, "passes": 2}}))
    run = interpret(fab.program, device, fab.plan.sheet)
    cut = [s for s in run.strokes if s.layer == "cut"]
    assert len(cut) == 2 and all(s.force == 30 for s in cut)
    with pytest.raises(FoldfabError, match=r"layers\.cut\.force"):
        fabricate(design, device, spec(layers={"cut": {"force": "hard"}}))


@pytest.mark.parametrize("device_name", DEVICES)
@pytest.mark.parametrize("strategy", ["force", "perforate", "two-sided"])
@pytest.mark.parametrize("job", JOBS, ids=[j.stem for j in JOBS])
def test_reported_travel_is_the_programs(job, strategy, device_name):
    """The optimizer's travel figures (the report's "pen-up travel") are what the program does:
    the interpreter's pen-up moves, park at every pause included, before and after optimizing."""
    device = load_device(device_name)
    fab = fabricate(load_design(job), device, spec(strategy=strategy, **whole(job)))
    unoptimized = finish_plan(fab.layout, device, fab.spec, optimize="none")
    for plan, figures in ((fab.plan, fab.travel_after), (unoptimized, fab.travel_before)):
        run = interpret(write_program(plan, device), device, plan.sheet)
        rounding = (len(run.travels) + 1) * 1.5 * device.resolution
        assert figures["total"] == pytest.approx(run.travel_length, abs=rounding)


@pytest.mark.parametrize("device_name", DEVICES)
def test_a_job_starts_and_ends_at_the_park_position(device_name, tmp_path):
    """With the park position away from the device origin, the program, its interpretation (so
    the preview and the estimate) and the optimizer's travel all start where the pen waits."""
    text = Path(load_device(device_name).source).read_text()
    assert "park = [0, 0]" in text
    profile = tmp_path / "parked.toml"
    profile.write_text(text.replace("park = [0, 0]", "park = [100, 120]"))
    device = load_device(str(profile))
    fab = fabricate(load_design(ROOT / "jobs" / "star.toml"), device, spec(strategy="two-sided"))
    run = interpret(fab.program, device, fab.plan.sheet)
    park = device.frame(fab.plan.sheet).to_sheet(np.array([[100.0, 120.0]]) * device.units_per_mm)[0]
    np.testing.assert_allclose(run.travels[0].start, park, atol=device.resolution)
    np.testing.assert_allclose(run.travels[-1].end, park, atol=device.resolution)
    rounding = (len(run.travels) + 1) * 1.5 * device.resolution
    assert fab.travel_after["total"] == pytest.approx(run.travel_length, abs=rounding)
    layers = estimate(run, device).layers.values()  # the report's and the preview legend's rows
    assert sum(layer.travel_length for layer in layers) == pytest.approx(run.travel_length, abs=1e-6)


@pytest.mark.parametrize("device_name", ["graphtec-ce6000", "grbl"])
def test_reported_travel_counts_the_park_at_a_tool_change(device_name):
    """A cutter without a tool changer parks for the operator to load the cut's own tool (and a
    layer drawn twice comes back to its start in between)."""
    device = load_device(device_name)
    layers = {"cut": {"pen": 2}, "mountain": {"passes": 2}}
    fab = fabricate(load_design(ROOT / "jobs" / "star.toml"), device, spec(layers=layers))
    run = interpret(fab.program, device, fab.plan.sheet)
    assert [p.message for p in run.pauses] == ["Load tool 2 for the cut pass, then resume."]
    assert fab.travel_after["layers"]["at pauses"] > 0
    rounding = (len(run.travels) + 1) * 1.5 * device.resolution
    assert fab.travel_after["total"] == pytest.approx(run.travel_length, abs=rounding)


@settings(max_examples=40, deadline=None)
@given(width=st.floats(150, 450), height=st.floats(150, 450), margin=st.floats(0, 20),
       scale=st.floats(0.2, 1.0), flip=st.sampled_from(["left", "top"]))
def test_two_sided_placement_keeps_both_sides_within_reach(width, height, margin, scale, flip):
    """The HP 7475A reaches only part of a large sheet: a two-sided design is placed where it
    and its mirror image on the back both lie within reach, or refused by the placement with the
    reason (never by the program writer's last check)."""
    device = load_device("hp7475a")
    design = load_design(ROOT / "jobs" / "star.toml")
    table = {"strategy": "two-sided", "sheet": [width, height], "margin": margin, "scale": scale, "flip_edge": flip}
    try:
        fab = fabricate(design, device, parse_fabrication(table, "star"))
    except FoldfabError as exc:
        assert "reaches only" not in str(exc)
        assert "both sides of the sheet" in str(exc) or "no part of the sheet is reached on both sides" in str(exc) \
            or "leaves no room" in str(exc) or "under 10 of the device's steps" in str(exc)
        suggested = re.search(r'flip_edge = "(\w+)"', str(exc))
        if suggested:  # the flip an error suggests does reach both sides
            try:
                fabricate(design, device, parse_fabrication(dict(table, flip_edge=suggested[1]), "star"))
            except FoldfabError as again:
                assert "no part of the sheet is reached on both sides" not in str(again)
        return
    x0, y0, x1, y1 = device.frame(fab.plan.sheet).device_rect_on_sheet(*device.plottable_area)
    run = interpret(fab.program, device, fab.plan.sheet)
    points = np.concatenate([s.points for s in run.strokes])
    tol = device.resolution
    assert points[:, 0].min() >= x0 - tol and points[:, 0].max() <= x1 + tol
    assert points[:, 1].min() >= y0 - tol and points[:, 1].max() <= y1 + tol


def test_a_flip_that_takes_the_back_out_of_reach_says_so():
    device = load_device("hp7475a")
    design = load_design(ROOT / "jobs" / "star.toml")
    table = {"strategy": "two-sided", "sheet": "A3", "scale": 0.5, "flip_edge": "top"}
    with pytest.raises(FoldfabError, match=r"star.toml: hp7475a: the device reaches y 224\.\.416 mm of the 420 mm sheet, "
                                           r"and flipped top-bottom \(about the horizontal axis\) its back would need y 4\.\.196 mm: .*"
                                           r"flip_edge = \"left\""):
        fabricate(design, device, parse_fabrication(table, "star"))
    fabricate(design, device, parse_fabrication(dict(table, flip_edge="left"), "star"))


@pytest.mark.parametrize("flip", ["left", "top"])
def test_a_sheet_out_of_reach_either_way_suggests_no_flip(flip):
    device = load_device("hp7475a")  # reaches 416 x 259 mm of a 600 x 600 mm sheet
    design = load_design(ROOT / "jobs" / "star.toml")
    table = {"strategy": "two-sided", "sheet": [600, 600], "scale": 0.3, "flip_edge": flip}
    with pytest.raises(FoldfabError) as error:
        fabricate(design, device, parse_fabrication(table, "star"))
    assert "flipped either way the sheet is not reached on both sides" in str(error.value)
    assert "flip_edge =" not in str(error.value)


# --- scale = "fit" -----------------------------------------------------------------------------

@settings(max_examples=300, deadline=None)
@given(w=st.floats(0.5, 3000), h=st.floats(0.5, 3000), sheet=st.tuples(st.floats(20, 2000), st.floats(20, 2000)),
       reach=st.tuples(st.floats(-50, 500), st.floats(-50, 500), st.floats(10, 2500), st.floats(10, 2500)),
       margin=st.floats(0, 40), rotate=st.sampled_from(["auto", "yes", "no"]),
       flip=st.sampled_from([None, "left", "top"]))
def test_fitted_scale_is_accepted_and_a_hair_more_is_refused(w, h, sheet, reach, margin, rotate, flip):
    """For any design extent, sheet, device reach, margin, turn and (two-sided) flip, the fitted
    scale passes the same placement check as a given scale, lands inside the usable region, is
    the better of the two turns, and 1.001 times it is refused."""
    from foldfab.fabrication.layout import both_sides
    from foldfab.fabrication.placement import fit, largest_scale, usable

    bounds = (complex(-w / 3, 7.0), complex(2 * w / 3, 7.0 + h))
    area = (reach[0], reach[1], reach[0] + reach[2], reach[1] + reach[3])
    try:
        if flip:
            area = both_sides(area, sheet, flip)
        region = usable(sheet, area, margin)
    except FoldfabError as exc:
        assert "leaves no room" in str(exc) or "no part of the sheet is reached on both sides" in str(exc)
        return
    scale = largest_scale(bounds, region, rotate)
    placement = fit(bounds, sheet, area, margin, scale, rotate)
    assert placement.scale == scale
    corners = placement.apply(np.array([bounds[0], bounds[1], complex(bounds[0].real, bounds[1].imag),
                                        complex(bounds[1].real, bounds[0].imag)]))
    tol = 1e-9 * max(1.0, *sheet)
    assert corners.real.min() >= region[0] - tol and corners.real.max() <= region[2] + tol
    assert corners.imag.min() >= region[1] - tol and corners.imag.max() <= region[3] + tol
    for turn in {"auto": ["no", "yes"], "yes": ["yes"], "no": ["no"]}[rotate]:  # the better turn
        assert scale >= largest_scale(bounds, region, turn)
    # The check allows 1e-9 mm of rounding: 0.1 % more is refused wherever that is more than 1e-9 mm,
    # i.e. wherever the placed design is a micrometre or more across (fabricate refuses under ten plotter steps).
    if min(placement.size) >= 1e-3:
        with pytest.raises(FoldfabError, match="largest scale that fits is .*--scale fit"):
            fit(bounds, sheet, area, margin, scale * 1.001, rotate)


@pytest.mark.parametrize("device_name", DEVICES)
@pytest.mark.parametrize("strategy, flip", [("force", "left"), ("two-sided", "left"), ("two-sided", "top")])
def test_fit_places_the_design_at_the_largest_scale_the_device_takes(device_name, strategy, flip):
    """End to end: with scale = "fit" the plan of a job (its glue tab included) fills the usable
    region along one side, within the device's reach on both sides of a two-sided sheet; the
    fitted scale times 1.001 is refused by the same check."""
    design = load_design(ROOT / "jobs" / "vase-svg.toml")  # it has a glue tab
    device = load_device(device_name)
    table = {"strategy": strategy, "flip_edge": flip, "scale": "fit", "margin": 7}
    fab = fabricate(design, device, parse_fabrication(table, "vase"))
    assert fab.spec.scale == "fit" and "fitted to the sheet" in fab.placement_summary
    x0, y0, x1, y1 = device.frame(fab.plan.sheet).device_rect_on_sheet(*device.plottable_area)
    run = interpret(fab.program, device, fab.plan.sheet)
    points = np.concatenate([s.points for s in run.strokes])
    tol = 2 * device.resolution
    assert points[:, 0].min() >= max(7, x0) - tol and points[:, 1].min() >= max(7, y0) - tol
    assert points[:, 0].max() <= min(fab.plan.sheet[0] - 7, x1) + tol
    assert points[:, 1].max() <= min(fab.plan.sheet[1] - 7, y1) + tol
    with pytest.raises(FoldfabError, match="largest scale"):
        fabricate(design, device, parse_fabrication(dict(table, scale=fab.placement.scale * 1.001), "vase"))


# the hexagon's sheet, A4 landscape (297 mm across), is wider than the Portrait 3 takes (203 mm of reach)
@pytest.mark.parametrize("device_name", [name for name in DEVICES if name != "silhouette-portrait-3"])
def test_a_design_that_fits_keeps_scale_1_unless_fit_is_asked(device_name):
    design = load_design(ROOT / "jobs" / "hexagon-fig8a.toml")
    device = load_device(device_name)
    assert fabricate(design, device).placement.scale == 1.0
    fitted = fabricate(design, device, scale="fit")
    assert fitted.placement.scale > 1.0 and fitted.placement_summary.startswith("scale ")
    assert fabricate(design, device, scale=0.5).placement.scale == 0.5


@pytest.mark.parametrize("value", ["big", "Fit", "", True])
def test_scale_is_a_number_or_fit(value):
    with pytest.raises(FoldfabError, match=r'\[fabrication\]\.scale: expected a number > 0 or "fit" '):
        parse_fabrication({"scale": value}, "job.toml")


# --- perforation dashes are cuts ----------------------------------------------------------------

@pytest.mark.parametrize("device_name", DEVICES)
def test_perforation_dashes_take_the_cut_tool_in_the_emitted_program(device_name):
    """Read back from the program: every dash has the cut's pen, force, speed and (G-code) depth,
    so it cuts through; a job's [fabrication.layers.valley] still sets the valley dashes."""
    design = load_design(ROOT / "jobs" / "hexagon-fig8a.toml")
    device = load_device(device_name)
    cut = device.layers["cut"]

    def tools(run, layer):
        return {(s.pen, s.force, s.speed, s.pen_down) for s in run.strokes if s.layer == layer}
    fab = fabricate(design, device, spec(strategy="perforate"))
    run = interpret(fab.program, device, fab.plan.sheet)
    pen = None if device.protocol == "gcode" else cut.pen
    expected = {(pen, cut.force, cut.speed, cut.pen_down)}
    assert tools(run, "valley") == tools(run, "mountain") == tools(run, "cut") == expected
    assert len([s for s in run.strokes if s.layer == "valley"]) > 10  # dashes, not whole creases

    slow = 20.0 if device.dialect in ("graphtec", "roland") else 12.5
    fab = fabricate(design, device, spec(strategy="perforate", layers={"valley": {"speed": slow}}))
    run = interpret(fab.program, device, fab.plan.sheet)
    assert tools(run, "valley") == {(pen, cut.force, slow, cut.pen_down)}
    assert tools(run, "mountain") == expected


# --- layer settings a device does not have ------------------------------------------------------

@pytest.mark.parametrize("device_name", DEVICES)
def test_a_layer_setting_the_device_lacks_is_ignored_with_one_warning(device_name):
    design = load_design(ROOT / "jobs" / "hexagon-fig8a.toml")
    device = load_device(device_name)
    fab = fabricate(design, device, spec(layers={"valley": {"force": 30, "passes": 2}}))
    run = interpret(fab.program, device, fab.plan.sheet)
    valley = [s for s in run.strokes if s.layer == "valley"]
    if device.language.force:  # in both force ranges; out of the device's range stays an error
        assert fab.warnings == () and {s.force for s in valley} == {30}
        with pytest.raises(FoldfabError, match=r"layers\.valley\.force': expected a value in .*\[limits\] of"):
            fabricate(design, device, spec(layers={"valley": {"force": 300}}))
    else:
        assert len(fab.warnings) == 1
        assert re.fullmatch(rf".*hexagon-fig8a\.toml: \[fabrication\.layers\.valley\]\.force = 30 ignored: {device_name} has no "
                            r"force setting \(its language has no force command\)", fab.warnings[0])
        assert {s.force for s in valley} == {None}
    assert fab.plan.steps[0].tool.passes == 2  # the settings the device has still apply
    with pytest.raises(FoldfabError, match=r"layers\.valley\.force.*expected a number"):  # malformed: still an error
        fabricate(design, device, spec(layers={"valley": {"force": "hard"}}))
    with pytest.raises(FoldfabError, match=r"layers\.valley\.passes"):  # out of every device's range
        fabricate(design, device, spec(layers={"valley": {"passes": 0}}))
