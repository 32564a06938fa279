"""Creases as arrays: the straight-on pairing against a plain greedy reference, strokes as one
array of points and where each starts, and the lay-out's vpype layers holding those very lines."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from foldfab.design import load_design
from foldfab.devices import load_device
from foldfab.fabrication.layout import lay_out, layer_tools, place
from foldfab.fabrication.plan import collection
from foldfab.fabrication.scoring import (_chains, _straight_pairs, crease_lines, crease_strokes, split_strokes,
                                         stroke_segments)
from foldfab.fabrication.spec import job_spec
from helpers import ROOT


def greedy_pairs(at: list[int], unit: list[complex], real: list[bool], extra: int) -> list[int]:
    """The reference pairing, one vertex at a time: every pair of its slots costed by how little
    it goes straight on (an edge to the extra vertex: last), then taken cheapest first, ties in
    slot order, while both slots are free."""
    partner = [-1] * len(at)
    for vertex in sorted(set(at) - {extra}):
        slots = [k for k, v in enumerate(at) if v == vertex]
        pairs = sorted(((unit[i] * unit[j].conjugate()).real if real[i] and real[j] else 2.0, i, j)
                       for n, i in enumerate(slots) for j in slots[n + 1:])
        for _, i, j in pairs:
            if partner[i] < 0 and partner[j] < 0:
                partner[i], partner[j] = j, i
    return partner


# directions on a small integer lattice: their products are exact, so equal costs (ties) are common
directions = st.tuples(st.integers(-2, 2), st.integers(-2, 2)).map(lambda d: complex(*d))


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 5), directions, st.booleans()), max_size=40), st.integers(0, 5))
def test_straight_pairs_are_the_greedy_reference(slots, extras):
    """Vertices of any number of slots, with ties and edges to the extra vertex, pair as the
    plain per-vertex greedy pairs them; the extra vertex's own slots stay unpaired."""
    extra = 6
    slots = sorted(slots, key=lambda s: s[0]) + [(extra, 0j, False)] * extras
    at = [s[0] for s in slots]
    unit = [s[1] for s in slots]
    real = [s[2] and s[0] != extra for s in slots]
    got = _straight_pairs(np.array(at, dtype=np.intp), np.array(unit, dtype=complex), np.array(real, dtype=bool),
                          extra)
    assert got.tolist() == greedy_pairs(at, unit, real, extra)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 9), st.integers(0, 9)).filter(lambda e: e[0] != e[1]), max_size=30))
def test_strokes_are_the_chains_as_one_array(edges):
    """One array of points and where each stroke starts gives back the same polylines, and
    their segments are the strokes' own, none from one stroke to the next."""
    points = (np.arange(10) + 1) * np.exp(2.4j * np.arange(10))
    edges = np.array(edges, dtype=np.intp).reshape(-1, 2)
    lines = _chains(edges, points)
    flat, starts = np.concatenate(lines) if lines else np.zeros(0, complex), np.cumsum([0] + [len(x) for x in lines])[:-1]
    assert [x.tolist() for x in split_strokes(flat, starts)] == [x.tolist() for x in lines]
    segments = stroke_segments(flat, starts)
    assert segments.tolist() == [[a, b] for line in lines for a, b in zip(line[:-1].tolist(), line[1:].tolist())]


def test_split_strokes_are_views_that_do_not_overlap():
    points, starts = np.arange(7) * (1 + 1j), np.array([0, 2, 5])
    lines = split_strokes(points, starts)
    assert [len(line) for line in lines] == [2, 3, 2]
    assert all(np.shares_memory(line, points) for line in lines)
    assert not any(np.shares_memory(a, b) for a, b in zip(lines[:-1], lines[1:]))


def test_collection_holds_the_lines_themselves():
    """vpype's own constructor copies each line in a Python call of its own: the lay-out's
    collections take the arrays as they are."""
    lines = split_strokes(np.arange(6) * 1j, np.array([0, 2]))
    layer = collection(lines)
    assert len(layer) == 2 and all(a is b for a, b in zip(layer.lines, lines))
    layer.translate(1, 0)  # vpype's transforms change the lines in place: each its own points
    assert layer.lines[1].tolist() == [2j + 1, 3j + 1, 4j + 1, 5j + 1]


@pytest.mark.parametrize("job", ["hexagon-fig8a", "star"])
@pytest.mark.parametrize("strategy", ["force", "two-sided"])
def test_laid_out_layers_are_the_chained_creases(job, strategy):
    """The valley layer holds the valley creases chained, placed, in order; a two-sided job's
    mountains are the chained mountains mirrored."""
    design = load_design(ROOT / "jobs" / f"{job}.toml")
    device = load_device("graphtec-ce6000")
    spec = replace(job_spec(design.job), strategy=strategy)
    placement, sheet = place(design, device, spec)
    plan = lay_out(design, device, spec, placement, sheet, layer_tools(design, device, spec)[0])
    layers = {plan.document.layers[k].property("vp_name"): plan.document.layers[k] for k in plan.document.layers}
    cp = design.crease_pattern
    want = crease_lines(cp, "V", placement.apply(cp.vertices[:, 0] + 1j * cp.vertices[:, 1]))
    assert [x.tolist() for x in layers["valley"].lines] == [x.tolist() for x in want]
    points, starts = crease_strokes(cp, "M", placement.apply(cp.vertices[:, 0] + 1j * cp.vertices[:, 1]))
    mountains = split_strokes(points if strategy == "force" else sheet[0] - points.conj(), starts)
    assert [x.tolist() for x in layers["mountain"].lines] == [x.tolist() for x in mountains]
