"""The yardsticks benchmarks/bench_fabrication.py holds plans to, checked against every order
and direction of small random sets: the floor no order can beat, and the exact best order."""

from __future__ import annotations

import itertools
import sys
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from foldfab.devices import load_device
from foldfab.programs.estimate import move_times, travel_times
from helpers import ROOT

sys.path.insert(0, str(ROOT / "benchmarks"))
from bench_fabrication import optimal_travel, travel_floor  # noqa: E402

DEVICE = load_device("graphtec-ce6000")
DEVICES = [DEVICE, load_device("grbl")]  # one limit for every direction; per-axis limits
coordinate = st.integers(0, 300).map(float)
end = st.tuples(coordinate, coordinate)
stroke = st.tuples(end, end, st.sampled_from(["valley", "mountain"]))


def best_travel(strokes, park: complex, device=DEVICE) -> float:
    """The least travel time over every order (layers in order) and direction of ``strokes``."""
    layers = list(dict.fromkeys(s.layer for s in strokes))
    best = np.inf
    for order in itertools.permutations(strokes):
        if [layers.index(s.layer) for s in order] != sorted(layers.index(s.layer) for s in order):
            continue
        for flips in itertools.product((False, True), repeat=len(order)):
            pen, steps = np.array([park.real, park.imag]), []
            for s, flip in zip(order, flips):
                a, b = (s.points[-1], s.points[0]) if flip else (s.points[0], s.points[-1])
                steps.append(a - pen)
                pen = b
            steps.append(np.array([park.real, park.imag]) - pen)
            best = min(best, float(travel_times(np.array(steps), device.motion).sum()))
    return best


@settings(max_examples=40, deadline=None)
@given(raw=st.lists(stroke, min_size=1, max_size=5), park=end, device=st.sampled_from(DEVICES))
def test_no_order_of_the_strokes_travels_less_than_the_floor(raw, park, device):
    strokes = [SimpleNamespace(points=np.array([a, b]), layer=layer) for a, b, layer in raw]
    floor = travel_floor(strokes, complex(*park), device)
    assert floor <= best_travel(strokes, complex(*park), device) + 1e-9


@settings(max_examples=40, deadline=None)
@given(raw=st.lists(stroke, min_size=1, max_size=5), park=end, device=st.sampled_from(DEVICES))
def test_the_exact_order_is_the_best_of_every_order(raw, park, device):
    strokes = [SimpleNamespace(points=np.array([a, b]), layer=layer) for a, b, layer in raw]
    assert optimal_travel(strokes, complex(*park), device) == \
        pytest.approx(best_travel(strokes, complex(*park), device), abs=1e-9)


def test_the_exact_order_starts_a_closed_stroke_at_its_best_vertex():
    """A square outline after one crease: entered at its corner nearest the crease's end,
    left from that same corner for home."""
    crease = SimpleNamespace(points=np.array([[0.0, 10.0], [0.0, 20.0]]), layer="valley")
    square = np.array([[30.0, 20.0], [60.0, 20.0], [60.0, 50.0], [30.0, 50.0], [30.0, 20.0]])
    outline = SimpleNamespace(points=square, layer="cut")
    motion = DEVICE.motion
    # park at the origin: out 10 mm to the crease, 30 mm to the corner (30, 20), home sqrt(30² + 20²)
    expected = move_times(np.array([10.0, 30.0, np.hypot(30.0, 20.0)]), motion.travel_speed,
                          motion.acceleration).sum()
    assert optimal_travel([crease, outline], 0j, DEVICE) == pytest.approx(expected)
    assert optimal_travel([crease] * 19, 0j, DEVICE) is None  # more strokes than it orders exactly


@settings(max_examples=40, deadline=None)
@given(raw=st.lists(stroke, min_size=1, max_size=8), park=end)
def test_the_floor_counts_the_way_out_and_home(raw, park):
    """Whatever it relaxes, the floor still leaves the park position once and comes back once."""
    strokes = [SimpleNamespace(points=np.array([a, b]), layer=layer) for a, b, layer in raw]
    nearest = min(np.hypot(*(s.points - np.array(park)).T).min() for s in strokes)
    motion = DEVICE.motion
    assert travel_floor(strokes, complex(*park), DEVICE) >= \
        2 * float(move_times(np.array([nearest]), motion.travel_speed, motion.acceleration)[0]) - 1e-9
