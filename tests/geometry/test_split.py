"""Splitting a crease pattern into pieces joined by glue tabs (issue 20)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from foldfab.errors import DesignError
from foldfab.geometry import templates
from foldfab.geometry.crease_pattern import build_crease_pattern
from foldfab.geometry.reflection import reflect
from foldfab.geometry.split import auto_cuts, letters, split_pattern
from foldfab.geometry.stroke_font import GLYPHS, text_strokes
from helpers.pieces import assert_pieces_rebuild

profiles = st.integers(3, 7).flatmap(lambda j: st.tuples(
    st.lists(st.floats(-1, 1), min_size=j, max_size=j),
    st.lists(st.floats(5, 20), min_size=j - 1, max_size=j - 1)))


def _profile(us, steps, scale):
    return np.column_stack([np.array(us) * scale, np.concatenate([[0.0], np.cumsum(steps)])])


def _cuts(draw, high, most):
    return sorted(draw(st.sets(st.integers(1, high), max_size=min(most, high)))) if high >= 1 else []


@settings(max_examples=40, deadline=None)
@given(n=st.integers(2, 8).map(lambda k: 2 * k), radius=st.floats(40, 200), prof=profiles,
       tab=st.sampled_from([0.0, 0.3]), data=st.data())
def test_closed_pieces_glue_back_into_the_design(n, radius, prof, tab, data):
    """Closed designs, with and without the seam tab: every crease in exactly one piece."""
    grid = reflect(_profile(*prof, 0.3 * radius / n), templates.regular(n, radius))
    width = tab * grid.segment_lengths.min()
    assume(tab == 0 or width > 0.01)
    cp = build_crease_pattern(grid, 1.0, width)
    columns = _cuts(data.draw, grid.x.shape[1] - 2, 3)
    rows = _cuts(data.draw, grid.x.shape[0] - 2, 2)
    assume(columns or rows)
    try:
        pieces = split_pattern(grid, 1.0, width, columns, rows)
    except DesignError as exc:
        assert "glue_tab" in str(exc)   # a tab too wide for a narrow panel is the one refusal
        assume(False)
    assert len(pieces) == (len(columns) + 1) * (len(rows) + 1)
    assert_pieces_rebuild(cp, pieces)


@settings(max_examples=30, deadline=None)
@given(turns=st.lists(st.floats(-1.5, 1.5).filter(lambda t: abs(t) > 0.1), min_size=2, max_size=6),
       prof=profiles, data=st.data())
def test_open_pieces_glue_back_into_the_design(turns, prof, data):
    heading, p, pts = 0.0, np.zeros(2), [np.zeros(2)]
    for turn in turns:
        p = p + 80 * np.array([np.cos(heading), np.sin(heading)])
        pts.append(p)
        heading += turn
    pts.append(p + 80 * np.array([np.cos(heading), np.sin(heading)]))
    try:
        grid = reflect(_profile(*prof, 2.0), np.array(pts))
        cp = build_crease_pattern(grid, 1.0)
    except DesignError:
        assume(False)
    columns = _cuts(data.draw, grid.x.shape[1] - 2, 3)
    rows = _cuts(data.draw, grid.x.shape[0] - 2, 2)
    assume(columns or rows)
    pieces = split_pattern(grid, 1.0, 0.0, columns, rows)
    assert_pieces_rebuild(cp, pieces)


def _convex_ccw(points: np.ndarray, tol: float) -> bool:
    """Whether a polygon turns left (or runs straight) at every corner, enclosing some area."""
    e = np.roll(points, -1, axis=0) - points
    turn = e[:, 0] * np.roll(e, -1, axis=0)[:, 1] - e[:, 1] * np.roll(e, -1, axis=0)[:, 0]
    return bool(np.all(turn >= -tol) and turn.sum() > 0)


def _distance_to_polyline(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    a, b = line[:-1], line[1:]
    d = b - a
    t = np.clip(np.einsum("pij,ij->pi", points[:, None] - a, d) / np.maximum((d * d).sum(axis=1), 1e-300), 0, 1)
    return np.linalg.norm(points[:, None] - (a + t[..., None] * d), axis=2).min(axis=1)


@settings(max_examples=40, deadline=None)
@given(n=st.integers(2, 8).map(lambda k: 2 * k), radius=st.floats(40, 200), prof=profiles,
       tab=st.floats(0.05, 0.45), data=st.data())
def test_glue_tabs_are_convex_with_chamfered_ends(n, radius, prof, tab, data):
    """Every tab, of a cut or the seam: its faces convex quadrilaterals (or triangles), its
    glued edge the cut line, its outer edge shorter at both ends (chamfered) and never farther
    from the cut than the tab's width, every corner a corner of the piece's faces."""
    grid = reflect(_profile(*prof, 0.3 * radius / n), templates.regular(n, radius))
    width = tab * grid.segment_lengths.min()
    assume(width > 0.01)
    cp = build_crease_pattern(grid, 1.0, width)
    columns = _cuts(data.draw, grid.x.shape[1] - 2, 3)
    rows = _cuts(data.draw, grid.x.shape[0] - 2, 2)
    try:
        pieces = split_pattern(grid, 1.0, width, columns, rows)
    except DesignError as exc:
        assert "glue_tab" in str(exc)
        assume(False)
    size = float(np.ptp(cp.vertices, axis=0).max())
    tol = 1e-9 * size
    seam = cp.vertices[np.unique(cp.faces[cp.tab_faces])]
    assert seam[:, 1].min() == 0 and seam[:, 1].max() == pytest.approx(grid.arc[-1])
    for piece in [*pieces, None]:
        pc = cp if piece is None else piece.crease_pattern
        for f, poly in enumerate(pc.face_polygons()):
            if pc.tab_faces[f]:
                assert len(poly) in (3, 4) and _convex_ccw(pc.vertices[poly], tol), f"tab face {f} is not convex"
        if piece is None:   # the whole design's seam tab: its far corners' heights inside the cut's
            far = pc.vertices[np.setdiff1d(pc.faces[pc.tab_faces], pc.faces[~pc.tab_faces])]
            assert 0 < far[:, 1].min() and far[:, 1].max() < grid.arc[-1]
            continue
        for join in (j for j in piece.joins if j.tab):
            m = len(join.outline) // 2
            glued, outer = join.outline[:m], join.outline[m:][::-1]
            np.testing.assert_allclose(glued[:len(join.line)], join.line, atol=tol)   # glued along the cut
            assert np.all(np.abs(glued[:, join.across] - glued[0, join.across]) <= tol) or join.across == 0
            corners = np.linalg.norm(join.outline[:, None] - pc.vertices[None], axis=2).min(axis=1)
            assert np.all(corners <= tol), "the tab's outline is made of the piece's own corners"
            along = 1 - join.across
            low, high = sorted((glued[0, along], glued[-1, along]))
            ends = outer[[0, -1], along]
            # the seam tab stays as it is: chamfered where the design ends, cut square at a row's cut
            seam = join.across == 0 and piece.columns[1] == grid.x.shape[1] - 1
            bottom, top = (piece.rows[0] == 0, piece.rows[1] == grid.x.shape[0] - 1) if seam else (True, True)
            assert (not bottom or low + tol < ends[0]) and (not top or ends[1] < high - tol), "the ends are chamfered"
            assert abs(ends[1] - ends[0]) < high - low or not (bottom or top), "the outer edge is shorter"
            assert np.all(_distance_to_polyline(outer, glued) <= join.width + tol)


def _hexagon():
    grid = reflect(np.array([[0, 0], [4, 20], [0, 40], [3, 60]], float), templates.regular(8, 60))
    return grid, build_crease_pattern(grid, 1.0, 5.0)


def test_every_cut_has_one_tab_and_one_edge_with_the_same_letter():
    grid, cp = _hexagon()
    pieces = split_pattern(grid, 1.0, 5.0, [3, 6], [2])
    assert [p.number for p in pieces] == [1, 2, 3, 4, 5, 6] and {p.count for p in pieces} == {6}
    joins = [(j.letter, j.tab) for p in pieces for j in p.joins]
    for letter in {name for name, _ in joins}:
        assert sorted(tab for name, tab in joins if name == letter) == [False, True]
    # the seam tab stays, on the last piece of each row, and is lettered too
    assert pieces[2].crease_pattern.tab_faces.sum() == 2 + 4   # seam tab, and the tab row under it too
    assert all(p.marks for p in pieces)
    assert_pieces_rebuild(cp, pieces)


def test_pieces_need_no_more_than_their_cuts():
    grid, cp = _hexagon()
    [whole] = split_pattern(grid, 1.0, 5.0)
    assert not whole.joins and not whole.marks
    np.testing.assert_array_equal(whole.crease_pattern.vertices + whole.offset, cp.vertices)


@pytest.mark.parametrize("columns, rows, message", [
    ([0], [], r"\[fabrication\].split: 0 is not a cut"), ([9], [], "split: 9 is not a cut"), ([2, 2], [], "names a cut twice"),
    ([], [3], "split_height: 3 is not a cut")])
def test_cuts_off_the_pattern_are_refused(columns, rows, message):
    grid, _ = _hexagon()
    with pytest.raises(DesignError, match=message):
        split_pattern(grid, 1.0, 5.0, columns, rows)


def test_a_tab_wider_than_the_panel_it_lies_on_is_refused():
    grid = reflect(np.array([[0, 0], [4, 20], [4, 25], [3, 60]], float), templates.regular(8, 60))
    with pytest.raises(DesignError, match=r"glue_tab: 8 mm is longer than profile segment 1 .* \(5 mm\)"):
        split_pattern(grid, 1.0, 8.0, [], [1])


def test_letters_and_stroke_font():
    assert letters(3) == ["A", "B", "C"] and letters(28)[-2:] == ["AA", "AB"]
    strokes = text_strokes("1 OF 3", 6.0)
    points = np.concatenate(strokes)
    assert points[:, 1].min() >= 0 and points[:, 1].max() == pytest.approx(6.0)
    assert all(len(s) >= 2 for s in strokes)
    assert set("ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789 ") <= set(GLYPHS)


def _long_strip():
    """An open zig-zag strip 600 mm long and 60 mm tall: 12 mirrors, 50 mm apart."""
    pts = np.array([[50.0 * i, 10.0 * (i % 2)] for i in range(13)])
    grid = reflect(np.array([[0, 0], [0, 20], [0, 40], [0, 60]], float), pts)
    return grid, build_crease_pattern(grid, 1.0)


def test_auto_split_takes_the_fewest_even_pieces_that_fit():
    grid, cp = _long_strip()
    length = cp.sheet_size[0]
    room = (250.0, 190.0)
    fits = lambda w, h: w <= room[0] and h <= room[1]   # noqa: E731
    columns, rows = auto_cuts(grid, 0.0, fits)
    assert rows == []
    pieces = split_pattern(grid, 1.0, 0.0, columns, rows)
    assert len(pieces) == int(np.ceil(length / room[0]))
    sizes = [p.crease_pattern.sheet_size for p in pieces]
    assert all(fits(*s) for s in sizes)
    widths = [w for w, _ in sizes]
    assert max(widths) - min(widths) <= 2 * np.diff(grid.x[0]).max()   # even, to a panel
    assert_pieces_rebuild(cp, pieces)


def test_auto_split_cuts_across_the_height_when_the_design_is_taller_than_the_sheet():
    grid, cp = _long_strip()
    columns, rows = auto_cuts(grid, 0.0, lambda w, h: w <= 700 and h <= 45)
    assert columns == [] and rows == [1]   # 20 + 8 mm tab below, 40 above: [2] would make 48 + 20
    assert auto_cuts(grid, 0.0, lambda w, h: True) == ([], [])


def test_auto_split_refuses_a_panel_larger_than_the_sheet():
    grid, _ = _long_strip()
    with pytest.raises(DesignError, match=r"\[fabrication\].split: even one panel"):
        auto_cuts(grid, 0.0, lambda w, h: w <= 30)
