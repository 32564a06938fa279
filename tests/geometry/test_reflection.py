"""The reflection construction: invariants on every example job and on generated designs, closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from foldfab.geometry import templates
from foldfab.geometry.crease_pattern import build_crease_pattern
from foldfab.design import load_design
from foldfab.errors import DesignError
from foldfab.geometry.reflection import reflect
from helpers import JOB_FOLDER, JOBS
from helpers.invariants import assert_design_invariants


@pytest.mark.parametrize("job", JOBS, ids=[j.stem for j in JOBS])
def test_example_jobs_build_and_satisfy_invariants(job):
    design = load_design(job)
    assert len(design.penetrations) == 0
    assert_design_invariants(design.grid, design.crease_pattern, design.job.crease.flat_angle)


def test_examples_cover_the_paper():
    names = {j.stem for j in JOBS}
    assert {"hexagon-fig8a", "hexagon-fig8b", "diamond-fig9", "vase-svg", "star", "open-wave-fig11f", "helix-fig12"} <= names


def critical_offset(n: int, radius: float) -> float:
    return radius * math.sin(math.pi / n) * math.tan(math.pi / n)


@given(n=st.integers(2, 30).map(lambda k: 2 * k), radius=st.floats(5, 500),
       frac=st.floats(-0.98, 0.98), height=st.floats(1, 100))
def test_regular_closed_form(n, radius, frac, height):
    """Full segments alternate s - 2w cot(pi/n) (outside) and s + 2w cot(pi/n) (inside)."""
    w = frac * critical_offset(n, radius)
    grid = reflect(np.array([[w, 0.0], [w, height]]), templates.regular(n, radius))
    s = 2 * radius * math.sin(math.pi / n)
    cot = 1 / math.tan(math.pi / n)
    lengths = grid.segment_lengths[0]
    assert len(lengths) == n + 1
    full = lengths[1:-1]
    expected = np.where(np.arange(n - 1) % 2 == 0, s + 2 * w * cot, s - 2 * w * cot)
    np.testing.assert_allclose(full, expected, rtol=1e-9, atol=1e-9 * radius)
    # the two half sides at the seam are outside
    np.testing.assert_allclose(lengths[[0, -1]], s / 2 - w * cot, rtol=1e-9, atol=1e-9 * radius)
    # every line element is as long as the trajectory's perimeter (even n)
    np.testing.assert_allclose(lengths.sum(), n * s, rtol=1e-9)


@pytest.mark.parametrize("n", [4, 6, 8, 12])
def test_diamond_degenerates_exactly_at_critical_offset(n):
    radius = 40.0
    w = critical_offset(n, radius)
    grid = reflect(np.array([[w, 0.0], [-w, 10.0], [w, 20.0]]), templates.regular(n, radius))
    lengths = grid.segment_lengths
    assert np.all(lengths[0, 0::2] == 0) and np.all(lengths[0, 1::2] > 0)
    assert np.all(lengths[1, 1::2] == 0) and np.all(lengths[1, 0::2] > 0)
    cp = build_crease_pattern(grid)
    assert all(len(face) == 3 for face in cp.face_polygons())
    # merged vertices: the crease pattern has no zero-length edge
    assert cp.edge_lengths.min() > 1e-6
    # a hair beyond the critical offset is invalid, and the message says what to reduce
    with pytest.raises(DesignError, match=r"line element 0 .* reduce u of profile point 0 .* at most"):
        reflect(np.array([[w * (1 + 1e-6), 0.0], [0.0, 10.0]]), templates.regular(n, radius))


def test_line_element_alternates_mountain_and_valley():
    """A profile ridge folds one way outside and the other way inside: reflection flips the paper."""
    design = load_design(JOB_FOLDER / "hexagon-fig8b.toml")
    cp = design.crease_pattern
    horizontal = cp.vertices[cp.edges[:, 0], 1] == cp.vertices[cp.edges[:, 1], 1]
    ridge = horizontal & np.isclose(cp.vertices[cp.edges[:, 0], 1], design.grid.arc[1])
    order = np.argsort(cp.vertices[cp.edges[ridge, 0], 0])
    kinds = cp.assignment[ridge][order]
    assert list(kinds) == ["M" if k % 2 == 0 else "V" for k in range(len(kinds))]


def test_odd_corner_count_cannot_close():
    with pytest.raises(DesignError, match="even number of corners.*has 5"):
        reflect(np.array([[0, 0], [1, 5]]), templates.regular(5, 40))


def test_closed_trajectory_starting_at_a_corner_uses_the_mirror_as_seam():
    square = np.array([[0, 0], [40, 0], [40, 40], [0, 40], [0, 0]], float)
    grid = reflect(np.array([[3.0, 0.0], [0.0, 10.0], [3.0, 20.0]]), square)
    assert grid.closed and grid.corner_seam and grid.corners == 4
    cp = build_crease_pattern(grid)
    assert_design_invariants(grid, cp, 1.0)
    # the seam edges are not perpendicular: their x depends on u
    assert grid.x[0, 0] != grid.x[1, 0]


def test_straight_corners_make_no_mirror():
    with_midpoints = np.array([[0, 0], [20, 0], [40, 0], [40, 20], [40, 40]], float)
    grid = reflect(np.array([[2.0, 0.0], [0.0, 10.0]]), with_midpoints)
    assert grid.corners == 1 and grid.x.shape[1] == 3


def test_a_fold_flat_onto_itself_is_an_error():
    """A mirror perpendicular to the paper folds it 180 degrees: the model cannot tell M from V."""
    rising = np.array([[0, 0, 0], [10, 0, 0], [20, 0, 5]], float)
    with pytest.raises(DesignError, match="folds flat onto itself"):
        build_crease_pattern(reflect(np.array([[0.0, 0.0], [0.0, 1.0]]), rising))


def test_closed_3d_trajectory_that_does_not_close_is_an_error():
    skew = np.array([[0, 0, 0], [40, 0, 0], [40, 40, 10], [0, 40, 30], [0, 0, 0]], float)
    with pytest.raises(DesignError, match="closed 3D trajectory does not close|even number"):
        reflect(np.array([[1.0, 0.0], [0.0, 10.0]]), skew)


@pytest.mark.parametrize("profile, trajectory, message", [
    ([[0, 0]], [[0, 0], [10, 0]], "profile: needs at least 2 points"),
    ([[0, 0], [0, 0], [1, 1]], [[0, 0], [10, 0]], "profile: points 0 and 1 are the same point"),
    ([[0, 0], [1, 1]], [[0, 0], [10, 0], [10, 0]], "trajectory: points 1 and 2 are the same point"),
    ([[0, 0], [1, float("nan")]], [[0, 0], [10, 0]], "profile: point 1 is not a finite number"),
    ([[0, 0], [1, 1]], [[0, 0], [10, 0], [0, 0]], "turns back on itself"),
    ([[0, 0], [1, 1]], [[0, 0, 0], [0, 0, 10]], "first segment is vertical"),
])
def test_invalid_polylines(profile, trajectory, message):
    with pytest.raises(DesignError, match=message):
        reflect(np.array(profile, float), np.array(trajectory, float))


# --- property-based: generated valid designs -------------------------------------------------

profiles = st.integers(2, 10).flatmap(lambda j: st.tuples(
    st.lists(st.floats(-1, 1), min_size=j, max_size=j),
    st.lists(st.floats(0.5, 20), min_size=j - 1, max_size=j - 1)))


def _profile(us, steps, scale):
    v = np.concatenate([[0.0], np.cumsum(steps)])
    return np.column_stack([np.array(us) * scale, v])


def _build_or_reject(profile, trajectory, flat_angle=1.0):
    try:
        grid = reflect(profile, trajectory)
        cp = build_crease_pattern(grid, flat_angle)
    except DesignError:
        assume(False)
    return grid, cp


@settings(max_examples=60, deadline=None)
@given(n=st.integers(2, 20).map(lambda k: 2 * k), radius=st.floats(10, 300), prof=profiles,
       flat=st.sampled_from([0.0, 1.0, 5.0]))
def test_generated_regular_designs(n, radius, prof, flat):
    profile = _profile(*prof, 0.95 * critical_offset(n, radius))
    grid, cp = _build_or_reject(profile, templates.regular(n, radius), flat)
    assert_design_invariants(grid, cp, flat)
    np.testing.assert_allclose(grid.segment_lengths.sum(axis=1), 2 * n * radius * math.sin(math.pi / n), rtol=1e-9)


@settings(max_examples=60, deadline=None)
@given(points=st.integers(2, 8), outer=st.floats(20, 200), ratio=st.floats(0.3, 0.9), prof=profiles)
def test_generated_star_designs(points, outer, ratio, prof):
    profile = _profile(*prof, 0.05 * outer * ratio / points)
    grid, cp = _build_or_reject(profile, templates.star(points, outer, outer * ratio))
    assert grid.corners == 2 * points
    assert_design_invariants(grid, cp, 1.0)


@settings(max_examples=60, deadline=None)
@given(turns=st.lists(st.tuples(st.floats(10, 100), st.floats(-2.5, 2.5)), min_size=1, max_size=8),
       rise=st.lists(st.floats(-0.5, 0.5), min_size=8, max_size=8), planar=st.booleans(), prof=profiles)
def test_generated_open_designs(turns, rise, planar, prof):
    """Open trajectories, planar or 3D: every invariant holds whenever the design is valid."""
    heading, p = 0.0, np.zeros(3)
    pts = [p.copy()]
    for i, (length, turn) in enumerate(turns):
        step = np.array([math.cos(heading), math.sin(heading), 0.0 if planar else rise[i]])
        p = p + length * step / np.linalg.norm(step[:2])
        pts.append(p.copy())
        heading += turn
    profile = _profile(*prof, 3.0)
    grid, cp = _build_or_reject(profile, np.array(pts))
    assert_design_invariants(grid, cp, 1.0)
    # open: every line element starts at x = 0 and ends at the trajectory's length
    assert np.allclose(grid.x[:, 0], 0) and np.allclose(grid.x[:, -1], grid.x[0, -1])


@settings(max_examples=30, deadline=None)
@given(n=st.integers(2, 10).map(lambda k: 2 * k), radius=st.floats(20, 200), prof=profiles,
       tab_frac=st.floats(0.05, 0.9))
def test_glue_tab_lies_on_the_first_segment(n, radius, prof, tab_frac):
    profile = _profile(*prof, 0.5 * critical_offset(n, radius))
    grid = reflect(profile, templates.regular(n, radius))
    tab = tab_frac * grid.segment_lengths[:, 0].min()
    assume(tab > 1e-6)
    cp = build_crease_pattern(grid, 1.0, tab)
    assert_design_invariants(grid, cp, 1.0)
    assert cp.tab_faces.sum() == len(profile) - 1
    width, _ = cp.sheet_size
    assert width == pytest.approx(np.ptp(grid.x) + tab, rel=1e-9) or width >= np.ptp(grid.x)


@pytest.mark.parametrize("closed", [False, True])
@pytest.mark.parametrize("turn", [1e-11, 1e-9, 5e-8])
def test_a_corner_that_barely_turns_is_straight(turn, closed):
    """A point a hair off the straight line (rounding, a digitised path) adds no mirror: the design
    is the one without it, and no arithmetic divides by a mirror that runs along the path."""
    import warnings

    profile = np.array([[0.0, 0.0], [3.0, 10.0], [0.0, 20.0]])
    square = np.array([[0, 0], [100, 0], [100, 100], [0, 100], [0, 0]], dtype=float)
    plain = square if closed else square[:3]
    bent = np.insert(plain, 1, [50, 25 * turn], axis=0)  # the path turns there by 2 * (25 turn) / 50
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got, want = reflect(profile, bent), reflect(profile, plain)
    np.testing.assert_allclose(got.x, want.x, atol=1e-6)
    np.testing.assert_allclose(got.points, want.points, atol=1e-6)


def test_a_shallow_corner_that_breaks_the_design_is_named_with_its_turn():
    profile = np.array([[0.0, 0.0], [3.0, 10.0], [0.0, 20.0]])
    with pytest.raises(DesignError, match=r"the mirror at trajectory point 1 \(100, 0\) turns the path by only "
                                          r"0\.0057 degrees.*if that point belongs on a straight line, remove it"):
        reflect(profile, np.array([[0, 0], [100, 0], [200, 0.01], [300, 1]]))


@pytest.mark.parametrize("miss", [0.0, 1.8e-15, 1e-10, 2e-7])
def test_a_path_that_ends_a_hair_from_its_start_is_closed(miss):
    """Closure is judged to a billionth of the design's size (an SVG path closed with relative
    moves ends 1e-15 off its start), and the closed design is the one of the exact loop."""
    profile = np.array([[0.0, 0.0], [3.0, 10.0], [0.0, 20.0]])
    hexagon = np.array(templates.regular(6, 40), dtype=float)  # closed: its last point is its first
    exact = reflect(profile, hexagon)
    near = hexagon.copy()
    near[-1, 0] += miss
    got = reflect(profile, near)
    assert exact.closed
    if miss > 1e-9 * 80:  # 80 mm across: 2e-7 is a real gap, the path stays open
        assert not got.closed
        return
    assert got.closed and got.corners == exact.corners
    np.testing.assert_allclose(got.x, exact.x, atol=1e-9)
    np.testing.assert_allclose(got.points, exact.points, atol=1e-9)


def test_a_hundred_thousand_reflections_still_close():
    """Rounding over 100,000 mirrors (1.2e-9) is no failure to close."""
    grid = reflect(np.array([[0.0, 0.0], [0.0, 20.0]]), templates.regular(100_000, 40_000))
    assert grid.closed and grid.corners == 100_000
