"""The whole-layer stroke sort (foldfab.fabrication.sort): every stroke once, either way round; the
greedy walk exactly the plain O(n²) one; never more travel than it; deterministic; and on every
example job no more pen-up travel than vpype's own ``linemerge linesort``."""

from __future__ import annotations

import dataclasses
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from helpers import ROOT
from hypothesis import given, settings
from hypothesis import strategies as st

from foldfab.design import load_design
from foldfab.devices import load_device
from foldfab.fabrication import sort
from foldfab.fabrication.layout import build_plan, park_position
from foldfab.fabrication.optimize import travel
from foldfab.fabrication.plan import PlotPlan
from foldfab.fabrication.sort import StrokeEnds, greedy_order, nearest_order, nearest_orders
from foldfab.fabrication.spec import parse_fabrication


def reference(starts: np.ndarray, ends: np.ndarray, pen: complex) -> tuple[list[int], list[bool]]:
    """The plain greedy walk: from the pen, the undrawn end nearest by ``dx*dx + dy*dy``, ties to
    the lowest end index (stroke i's first point 2i, its last 2i + 1), over every end each time."""
    points = np.column_stack([starts, ends]).ravel()
    undrawn = np.ones(len(points), dtype=bool)
    order, flipped = [], []
    x, y = pen.real, pen.imag
    for _ in range(len(starts)):
        dx, dy = points.real - x, points.imag - y
        squared = np.where(undrawn, dx * dx + dy * dy, np.inf)
        end = int(np.argmin(squared))  # the first of equal minima
        undrawn[end & ~1:(end | 1) + 1] = False
        order.append(end >> 1)
        flipped.append(bool(end & 1))
        leave = points[end ^ 1]
        x, y = leave.real, leave.imag
    return order, flipped


def drawn(starts, ends, order, flipped) -> tuple[np.ndarray, np.ndarray]:
    """Where each stroke, in drawing order, is entered and left."""
    order, flipped = np.asarray(order, dtype=int), np.asarray(flipped, dtype=bool)
    return np.where(flipped, ends[order], starts[order]), np.where(flipped, starts[order], ends[order])


def pen_up(starts, ends, order, flipped, pen: complex) -> float:
    into, out = drawn(starts, ends, order, flipped)
    if not len(into):
        return 0.0
    return abs(into[0] - pen) + float(np.abs(into[1:] - out[:-1]).sum())


# Coarse grids make ties and shared ends common (crease patterns are full of both); fine ones do not.
grid = st.sampled_from([1.0, 0.5, 1e-3])
coordinate = st.integers(-20, 20)
stroke = st.tuples(coordinate, coordinate, coordinate, coordinate)


def strokes_of(raw, step) -> tuple[np.ndarray, np.ndarray]:
    values = np.array(raw, dtype=float).reshape(-1, 4) * step
    return values[:, 0] + 1j * values[:, 1], values[:, 2] + 1j * values[:, 3]


@settings(max_examples=200, deadline=None)
@given(raw=st.lists(stroke, max_size=80), step=grid, pen=st.tuples(coordinate, coordinate),
       neighbours=st.sampled_from([2, 3, 16]), first=st.sampled_from([0, 1, 4]), block=st.sampled_from([5, 1 << 16]))
def test_the_greedy_walk_is_exactly_the_plain_one(raw, step, pen, neighbours, first, block):
    """Few neighbours per end make the walk fall back on its second tree (and rebuild it) often;
    few or no ends kept in order of choice, on the rest of each end's row; small blocks, many
    lookups of the neighbours."""
    starts, ends = strokes_of(raw, step)
    pen = complex(*pen) * step
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(sort, "NEIGHBOURS", neighbours)
        patch.setattr(sort, "FIRST", first)
        patch.setattr(sort, "BLOCK", block)
        order, flipped = greedy_order(starts, ends, pen)
    expected = reference(starts, ends, pen)
    assert (order.tolist(), flipped.tolist()) == expected


@settings(max_examples=150, deadline=None)
@given(raw=st.lists(stroke, max_size=120), step=grid, pen=st.tuples(coordinate, coordinate))
def test_the_order_draws_every_stroke_once_and_never_travels_more_than_the_greedy_walk(raw, step, pen):
    starts, ends = strokes_of(raw, step)
    pen = complex(*pen) * step
    order, flipped = nearest_order(starts, ends, pen)
    assert sorted(order.tolist()) == list(range(len(starts)))
    assert len(flipped) == len(order)
    into, out = drawn(starts, ends, order, flipped)
    # each stroke's points are its own, as they were or reversed: its two ends, swapped when flipped
    assert np.array_equal(np.where(flipped, out, into), starts[order])
    assert np.array_equal(np.where(flipped, into, out), ends[order])
    assert pen_up(starts, ends, order, flipped, pen) <= pen_up(starts, ends, *reference(starts, ends, pen), pen) + 1e-9


@settings(max_examples=100, deadline=None)
@given(raw=st.lists(stroke, max_size=60), step=grid, pens=st.lists(st.tuples(coordinate, coordinate), min_size=1,
                                                                     max_size=3))
def test_orders_from_several_pens_share_one_neighbour_query_and_are_each_the_order_from_that_pen(raw, step, pens):
    """The walks from the pen and from the goal share the layer's neighbour table: neither walk may
    leave a mark on it that changes the other (each as if sorted alone)."""
    starts, ends = strokes_of(raw, step)
    pens = [complex(*pen) * step for pen in pens]
    together = nearest_orders(StrokeEnds(starts, ends), pens)
    assert len(together) == len(pens)
    for pen, (order, flipped) in zip(pens, together):
        alone = nearest_order(starts, ends, pen)
        assert (order.tolist(), flipped.tolist()) == (alone[0].tolist(), alone[1].tolist())


@settings(max_examples=150, deadline=None)
@given(raw=st.lists(stroke, max_size=60), step=grid, reach=st.sampled_from([0.3, 1.2, 2.5]),
       neighbours=st.sampled_from([3, 16]), block=st.sampled_from([5, 1 << 16]))
def test_ends_meet_where_two_strokes_have_ends_within_the_tolerance(raw, step, reach, neighbours, block):
    """The layer's neighbour table answers whether vpype's ``linemerge`` has anything to join, as
    comparing every two ends would (the tolerances fall between the grid's distances)."""
    starts, ends = strokes_of(raw, step)
    points = np.column_stack([starts, ends]).ravel()
    apart = np.abs(points[:, None] - points[None, :])
    other = (np.arange(len(points))[:, None] >> 1) != (np.arange(len(points))[None, :] >> 1)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(sort, "NEIGHBOURS", neighbours)
        patch.setattr(sort, "BLOCK", block)
        table = StrokeEnds(starts, ends)
    assert table.meet(reach * step) == bool(np.any(other & (apart <= reach * step)))


def test_on_random_sets_moving_stragglers_travels_less():
    rng = np.random.default_rng(11)
    for count in (50, 500, 3000):
        starts = rng.random(count) * 300 + 1j * rng.random(count) * 200
        ends = starts + (rng.random(count) - 0.5) * 10 + 1j * (rng.random(count) - 0.5) * 10
        ours = pen_up(starts, ends, *nearest_order(starts, ends, 0j), 0j)
        assert ours < 0.97 * pen_up(starts, ends, *reference(starts, ends, 0j), 0j)


def test_the_order_is_the_same_every_time_and_in_parallel_threads():
    rng = np.random.default_rng(12)
    cases = []
    for count in range(2000, 2020):
        starts = np.round(rng.random(count) * 40) + 1j * np.round(rng.random(count) * 40)  # many ties
        cases.append((starts, starts + rng.integers(0, 3, count) + 1j * rng.integers(0, 3, count), 0j))
    alone = [nearest_order(*case) for case in cases]
    with ThreadPoolExecutor(8) as pool:
        together = list(pool.map(lambda case: nearest_order(*case), cases))
    for (a, fa), (b, fb) in zip(alone, together):
        assert a.tolist() == b.tolist() and fa.tolist() == fb.tolist()


def test_no_strokes_and_one_stroke():
    assert [a.tolist() for a in nearest_order(np.zeros(0, complex), np.zeros(0, complex), 5j)] == [[], []]
    assert [a.tolist() for a in nearest_order(np.array([10 + 0j]), np.array([1 + 0j]), 0j)] == [[0], [True]]


def _vpype_plain(plan: PlotPlan) -> PlotPlan:
    import vpype_cli

    return PlotPlan(vpype_cli.execute("linemerge linesort", plan.document), plan.steps, plan.sheet)


@pytest.mark.parametrize("device_name", ["graphtec-ce6000", "grbl"])
@pytest.mark.parametrize("job", sorted(p.name for p in (ROOT / "jobs").glob("*.toml")))
def test_every_example_job_travels_no_more_than_vpypes_linemerge_linesort(job, device_name):
    """vpype's pipeline, run here on the same layers, from the same park position and through the
    same pauses, as the yardstick (the per-job figures are in docs/benchmarks.md)."""
    device = load_device(device_name)
    design = load_design(ROOT / "jobs" / job)
    # bench_fabrication.py's settings (where foldfab 43f7afb's tiles travelled more than vpype on the
    # GRBL: both hexagons and the star); the lantern fits the GRBL's area only smaller
    scale = "fit" if (job, device_name) == ("lantern-three-sheets.toml", "grbl") else 0.5
    spec = parse_fabrication({"sheet": "A3", "margin": 5, "scale": scale}, job)
    raw = build_plan(design, device, dataclasses.replace(spec, optimize="none"))
    park = park_position(device, raw.sheet)
    theirs = travel(_vpype_plain(raw), park, device.tool_changer)["total"]
    ours = travel(build_plan(design, device, dataclasses.replace(spec, optimize="greedy")), park,
                  device.tool_changer)["total"]
    assert ours <= theirs


@pytest.mark.parametrize("device_name", ["graphtec-ce6000", "grbl"])
@pytest.mark.parametrize("job", ["star.toml", "vase-svg.toml", "hexagon-fig8b.toml"])
def test_a_plan_travels_no_more_than_with_vpypes_orders_alone(job, device_name):
    """Choosing each layer's order by its own travel in and out can leave the next layer a worse
    start (the star on its own sheet: valleys 1 mm shorter, mountains 44 mm longer): the plan of
    vpype's orders alone, foldfab's before it had its own sort, is the fallback."""
    from foldfab.fabrication.optimize import _optimized
    from foldfab.fabrication.plan import device_steps
    from foldfab.fabrication.spec import job_spec

    device = load_device(device_name)
    design = load_design(ROOT / "jobs" / job)
    raw = build_plan(design, device, dataclasses.replace(job_spec(design.job), optimize="none"))
    park = park_position(device, raw.sheet)
    steps = [step for _, step in device_steps(raw, device.tool_changer)]
    theirs = _optimized(raw, steps, False, device.resolution, park, frozenset(), {}, mixed=False)
    ours = build_plan(design, device, job_spec(design.job))
    assert travel(ours, park, device.tool_changer)["total"] <= travel(theirs, park, device.tool_changer)["total"]


@settings(max_examples=100, deadline=None)
@given(raw=st.lists(stroke, max_size=80), step=grid, pen=st.tuples(coordinate, coordinate),
       neighbours=st.sampled_from([3, 5, 12, 40]))
def test_the_order_does_not_depend_on_how_many_neighbours_the_walk_looks_up(raw, step, pen, neighbours):
    """The width of the neighbour table is a matter of speed alone: the walk is exact whatever it
    is, and stragglers look for their places among their own :data:`~sort.PLACES` nearest ends."""
    starts, ends = strokes_of(raw, step)
    pen = complex(*pen) * step
    expected = nearest_order(starts, ends, pen)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(sort, "NEIGHBOURS", neighbours)
        order, flipped = nearest_order(starts, ends, pen)
    assert (order.tolist(), flipped.tolist()) == (expected[0].tolist(), expected[1].tolist())

