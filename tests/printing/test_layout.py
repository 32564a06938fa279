"""The template's layout, by invariants: tiles cover the pattern with the given overlap, the
crease polylines hold every edge once, alignment marks of neighbours meet, the model view
fits its box, and pieces each get their own pages."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from foldfab.design import load_design
from foldfab.printing.creases import STRAIGHT, arc_lengths, crease_polylines, trim
from foldfab.printing.marks import alignment_marks
from foldfab.printing.model_view import MAX_VIEW_FACES, grid_ids, model_view
from foldfab.printing.page import Text
from foldfab.printing.paper import PrintOptions, parse_paper
from foldfab.printing.template import build_template, lay_out
from foldfab.printing.tiles import tile, tile_patterns
from helpers import HEXAGON, JOBS
from helpers.cli import write_job

STAR = HEXAGON.parent / "star.toml"


@settings(max_examples=150, deadline=None)
@given(x0=st.floats(-500, 500), y0=st.floats(-500, 500), w=st.floats(1, 3000), h=st.floats(1, 2000),
       scale=st.floats(0.2, 3), paper=st.sampled_from([(210.0, 297.0), (297.0, 210.0), (215.9, 279.4), (100.0, 120.0)]),
       margin=st.floats(0, 12), overlap=st.floats(0, 15))
def test_tiles_cover_the_pattern_with_the_overlap_and_no_extra_tile(x0, y0, w, h, scale, paper, margin, overlap):
    bounds = (x0, y0, x0 + w, y0 + h)
    t = tile(bounds, paper, margin, overlap, scale)
    windows = np.array([t.window(r, c) for r in range(t.rows) for c in range(t.cols)])
    eps = 1e-6 * max(1.0, abs(x0), abs(y0), w, h)
    assert windows[:, 0].min() <= x0 + eps and windows[:, 2].max() >= x0 + w - eps
    assert windows[:, 1].min() <= y0 + eps and windows[:, 3].max() >= y0 + h - eps
    shared_x = t.area[2] - t.area[0] - t.step[0]
    if t.cols > 1:  # neighbours share the same strip of pattern, overlap mm wide when printed
        assert math.isclose((t.window(0, 0)[2] - t.window(0, 1)[0]) * scale, shared_x, abs_tol=1e-6)
    if t.rows > 1:
        assert math.isclose((t.window(1, 0)[3] - t.window(0, 0)[1]) * scale, t.area[3] - t.area[1] - t.step[1],
                            abs_tol=1e-6)
    # one column fewer would not reach across the pattern
    assert (t.cols - 1) * t.step[0] + shared_x < w * scale + 1e-6 or t.cols == 1
    # a pattern point maps onto its tile's area
    page = t.to_page(np.array([[x0 + w / 2, y0 + h / 2]]), 0, 0)
    wx0, wy0, wx1, wy1 = t.window(0, 0)
    if wx0 <= x0 + w / 2 <= wx1 and wy0 <= y0 + h / 2 <= wy1:
        assert t.area[0] - 1e-6 <= page[0, 0] <= t.area[2] + 1e-6


def test_a_wide_strip_turns_the_paper_unless_told():
    strip = [(0.0, 0.0, 500.0, 40.0)]
    a4 = (210.0, 297.0)
    turned = tile_patterns(strip, a4, True, 10, 6, 1.0, "A4")
    fixed = tile_patterns(strip, a4, False, 10, 6, 1.0, "A4")
    assert turned[0].paper == (297.0, 210.0) and turned[0].count < fixed[0].count
    assert parse_paper("A4 landscape") == ((297.0, 210.0), "A4 landscape", False)
    assert parse_paper("[300, 200]") == ((300.0, 200.0), "300 x 200 mm", False)


@pytest.mark.parametrize("job", JOBS, ids=[j.stem for j in JOBS])
def test_crease_polylines_hold_every_edge_once_and_run_straight_on(job):
    cp = load_design(job).crease_pattern
    lines = crease_polylines(cp, ("B", "M", "V", "F"))
    index = {tuple(p): i for i, p in enumerate(cp.vertices.tolist())}
    drawn = []
    for kind, polylines in lines.items():
        for line in polylines:
            ids = [index[tuple(p)] for p in line.tolist()]
            drawn += [(kind, min(a, b), max(a, b)) for a, b in zip(ids[:-1], ids[1:])]
            d = np.diff(line, axis=0)
            d /= np.linalg.norm(d, axis=1)[:, None]
            assert np.all(np.einsum("ij,ij->i", d[:-1], d[1:]) > STRAIGHT - 1e-9)
    expected = [(str(k), min(a, b), max(a, b)) for k, (a, b) in zip(cp.assignment, cp.edges.tolist())]
    assert sorted(drawn) == sorted(expected)


def test_alignment_targets_of_neighbouring_tiles_meet_on_the_pattern():
    design = load_design(STAR)
    template = build_template(design, PrintOptions())
    t = template.tilings[0]
    assert t.cols == 2

    def centres(col):  # the targets' circle centres, back in pattern coordinates
        marks = alignment_marks(t, 0, col)
        circles = [p for p in marks.polylines if len(p) > 2]
        left, top = t.origin[0] + col * t.step[0], t.origin[1]
        return sorted((round(float(c[0] - t.area[0] + left), 6), round(float(c[1] - t.area[3] + top), 6))
                      for c in (p[:-1].mean(axis=0) for p in circles))

    assert len(centres(0)) == 2 and centres(0) == centres(1)


@pytest.mark.parametrize("job", JOBS, ids=[j.stem for j in JOBS])
def test_model_view_draws_every_face_inside_its_box(job):
    cp = load_design(job).crease_pattern
    box = (10.0, 20.0, 110.0, 90.0)
    shapes = model_view(cp, box)
    assert len(shapes) == len(cp.faces)
    points = np.concatenate([s.points for s in shapes])
    assert np.all(points >= np.array(box[:2]) - 1e-6) and np.all(points <= np.array(box[2:]) + 1e-6)
    ids = grid_ids(cp)
    j, k = cp.face_grid.T
    assert np.array_equal(np.stack([ids[j, k], ids[j, k + 1], ids[j + 1, k + 1], ids[j + 1, k]], 1), cp.faces)


def test_a_large_model_is_drawn_on_a_coarser_grid(tmp_path):
    points = ", ".join(f"[{0.5 * (i % 2)}, {2 * i}]" for i in range(301))
    job = write_job(tmp_path, f"[profile]\npoints = [{points}]\n[trajectory]\ntemplate = \"regular\"\n"
                              "corners = 60\nradius = 300\n")
    cp = load_design(job).crease_pattern
    assert len(cp.faces) > MAX_VIEW_FACES
    shapes = model_view(cp, (0.0, 0.0, 100.0, 100.0))
    assert 0 < len(shapes) <= MAX_VIEW_FACES


def test_pieces_are_laid_out_each_on_its_own_pages():
    design = load_design(STAR)
    cp = design.crease_pattern
    template = lay_out([cp, cp], "two", cp, True, PrintOptions())
    one = build_template(design, PrintOptions())
    assert len(template.pages) == 1 + 2 * (len(one.pages) - 1)
    assert template.page_of(1, 0, 0) == template.page_of(0, 0, template.tilings[0].cols - 1) + 1
    header = [i.text for i in template.pages[template.page_of(1, 0, 0)].items if isinstance(i, Text)]
    assert any("piece 2 of 2" in text for text in header)


@settings(max_examples=200, deadline=None)
@given(points=st.lists(st.tuples(st.floats(-100, 100), st.floats(-100, 100)), min_size=2, max_size=12),
       window=st.tuples(st.floats(-120, 100), st.floats(-120, 100), st.floats(1, 100), st.floats(1, 100)),
       period=st.sampled_from([0.0, 4.5, 5.6]))
def test_trim_keeps_every_segment_near_the_window_and_the_dash_phase(points, window, period):
    line = np.array(points, float)
    arc = arc_lengths(line)
    box = (window[0], window[1], window[0] + window[2], window[1] + window[3])
    part = trim(line, arc, box, period)
    a, b = line[:-1], line[1:]
    reach = ((np.minimum(a[:, 0], b[:, 0]) <= box[2]) & (np.maximum(a[:, 0], b[:, 0]) >= box[0])
             & (np.minimum(a[:, 1], b[:, 1]) <= box[3]) & (np.maximum(a[:, 1], b[:, 1]) >= box[1]))
    if not reach.any():
        assert len(part) == 0
        return
    # the part is the line from some point on it: every vertex of a reaching segment is in it
    for i in np.nonzero(reach)[0]:
        for p in (line[i], line[i + 1]):
            assert np.any(np.all(np.isclose(part, p, atol=1e-9), axis=1))
    # it starts on some segment k and follows the line from vertex k + 1 on, at a whole number of
    # periods from the line's start (or at a vertex, without dashes)
    start, n = part[0], len(part)
    onto = [k for k in range(len(line) - 1)
            if np.hypot(*(start - line[k])) + np.hypot(*(line[k + 1] - start)) <= np.hypot(*(line[k + 1] - line[k])) + 1e-7
            and k + n <= len(line) and np.allclose(part[1:], line[k + 1:k + n], atol=1e-9)]
    assert onto
    whole = [abs(v - round(v)) < 1e-6 for k in onto for v in [(arc[k] + np.hypot(*(start - line[k]))) / (period or 1.0)]]
    assert any(whole) or period == 0
