"""SVG input: one path of an SVG file as a polyline in mm, y up from the page's bottom edge.

Expected coordinates are worked out by hand from the SVG rules (user units are
px without a viewBox; width/height and preserveAspectRatio map the viewBox onto
the page; group transforms apply), never by calling foldfab's own transform.
Curves are checked against a dense svgpathtools sampling converted with the
same, hand-written map.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st
from svgpathtools import CubicBezier, parse_path

from foldfab.design import load_design, profile_points, trajectory_points
from foldfab.errors import FoldfabError
from foldfab.job import load_job
from foldfab.geometry.svg_input import DEFAULT_TOLERANCE, read_svg_polyline
from helpers import JOB_FOLDER
from helpers.cli import write_job

PX = 25.4 / 96  # mm per CSS pixel
NS = 'xmlns="http://www.w3.org/2000/svg"'


def write_svg(folder: Path, body: str, attrs: str = 'width="100mm" height="50mm" viewBox="0 0 100 50"',
              name: str = "in.svg") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_text(f'<?xml version="1.0" encoding="UTF-8"?>\n<svg {NS} {attrs}>\n{body}\n</svg>\n', encoding="utf-8")
    return path


def read(file: Path, **kwargs) -> np.ndarray:
    return read_svg_polyline(file, **kwargs)


# --------------------------------------------------------------------------- page size and units

# (svg attributes, mm per user unit in x and y, page bottom in user units, viewBox min x)
PAGES = {
    "mm with viewBox 1:1": ('width="100mm" height="50mm" viewBox="0 0 100 50"', 1.0, 1.0, 50.0, 0.0),
    "cm with viewBox 2 units per mm": ('width="10cm" height="5cm" viewBox="0 0 200 100"', 0.5, 0.5, 100.0, 0.0),
    "inches": ('width="4in" height="2in" viewBox="0 0 4 2"', 25.4, 25.4, 2.0, 0.0),
    "px with viewBox": ('width="200px" height="100px" viewBox="0 0 100 50"', 2 * PX, 2 * PX, 50.0, 0.0),
    "px without viewBox": ('width="200px" height="100px"', PX, PX, 100.0, 0.0),
    "unitless without viewBox (px)": ('width="200" height="100"', PX, PX, 100.0, 0.0),
    # Without a viewBox a user unit is a px whatever unit width/height use.
    "mm without viewBox": ('width="100mm" height="50mm"', PX, PX, 50.0 / PX, 0.0),
    "viewBox with an origin and commas": ('width="100mm" height="50mm" viewBox="-10,20,100,50"', 1.0, 1.0, 70.0, -10.0),
    "points": ('width="72pt" height="36pt" viewBox="0 0 72 36"', 25.4 / 72, 25.4 / 72, 36.0, 0.0),
}


@pytest.mark.parametrize("attrs, sx, sy, bottom, min_x", PAGES.values(), ids=PAGES.keys())
def test_units_and_viewbox(tmp_path, attrs, sx, sy, bottom, min_x):
    user = np.array([[min_x + 1.0, bottom - 2.0], [min_x + 13.0, bottom - 2.0], [min_x + 13.0, bottom - 7.5]])
    d = "M " + " L ".join(f"{float(x)!r} {float(y)!r}" for x, y in user)
    got = read(write_svg(tmp_path, f'<path d="{d}"/>', attrs))
    expected = np.column_stack([(user[:, 0] - min_x) * sx, (bottom - user[:, 1]) * sy])
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)


def test_y_flip_top_of_page_is_highest_v(tmp_path):
    # A path from the bottom-left corner to the top edge and back down: the top point has the largest v.
    path = write_svg(tmp_path, '<path d="M 0 50 L 30 0 L 60 40"/>')
    got = read(path)
    np.testing.assert_allclose(got, [[0, 0], [30, 50], [60, 10]], atol=1e-12)
    assert int(np.argmax(got[:, 1])) == 1 and got[1, 1] == pytest.approx(50.0)


def test_example_vase_profile_starts_at_the_bottom(tmp_path):
    pts = read(JOB_FOLDER / "vase-profile.svg", path="profile", tolerance=0.05)
    np.testing.assert_allclose(pts[0], [0, 0], atol=1e-9)
    np.testing.assert_allclose(pts[-1], [2, 70], atol=1e-9)
    assert len(pts) > 10  # a curve, cut into many chords
    assert np.all(np.diff(pts[:, 1]) > 0)  # the vase rises all the way: v only grows


# --------------------------------------------------------------------------- viewport: width/height, preserveAspectRatio

# (svg attributes, three user points, where they land in mm).  The page is width x height; a
# missing side follows from the viewBox's aspect ratio.  The viewBox is scaled uniformly by
# min(width/vw, height/vh) (meet, the default) or max (slice) and aligned in the page: xMin at
# the left edge, xMax at the right; YMin at the page's top edge, YMax at its bottom (y is flipped).
VIEWPORTS = {
    "only width: height from the viewBox": (
        'width="100mm" viewBox="0 0 200 50"', [(0, 50), (200, 0), (50, 40)], [(0, 0), (100, 25), (25, 5)]),
    "only height: width from the viewBox": (
        'height="30mm" viewBox="10 0 200 60"', [(10, 60), (210, 0), (110, 30)], [(0, 0), (100, 30), (50, 15)]),
    "only width in px": (
        'width="200px" viewBox="0 0 100 50"', [(0, 50), (100, 0), (25, 25)],
        [(0, 0), (200 * PX, 100 * PX), (50 * PX, 50 * PX)]),
    "default meet, tall page: centred vertically": (
        'width="100mm" height="100mm" viewBox="0 0 200 100"', [(0, 100), (200, 0), (100, 50)],
        [(0, 25), (100, 75), (50, 50)]),
    "default meet, wide page: centred horizontally": (
        'width="200mm" height="50mm" viewBox="0 0 100 100"', [(0, 100), (100, 0), (50, 50)],
        [(75, 0), (125, 50), (100, 25)]),
    "xMidYMid meet written out": (
        'width="100mm" height="100mm" viewBox="0 0 200 100" preserveAspectRatio="xMidYMid meet"',
        [(0, 100), (200, 0), (100, 50)], [(0, 25), (100, 75), (50, 50)]),
    "xMinYMin meet, tall page: at the top": (
        'width="100mm" height="100mm" viewBox="0 0 200 100" preserveAspectRatio="xMinYMin meet"',
        [(0, 100), (200, 0), (100, 50)], [(0, 50), (100, 100), (50, 75)]),
    "xMinYMin meet, wide page: at the left": (
        'width="200mm" height="50mm" viewBox="0 0 100 100" preserveAspectRatio="xMinYMin meet"',
        [(0, 100), (100, 0), (50, 50)], [(0, 0), (50, 50), (25, 25)]),
    "xMaxYMax (meet implied), wide page: at the right": (
        'width="200mm" height="50mm" viewBox="0 0 100 100" preserveAspectRatio="xMaxYMax"',
        [(0, 100), (100, 0), (50, 50)], [(150, 0), (200, 50), (175, 25)]),
    "xMaxYMid meet with a viewBox origin": (
        'width="100mm" height="100mm" viewBox="-20 10 50 100" preserveAspectRatio="xMaxYMid meet"',
        [(-20, 110), (30, 10), (5, 60)], [(50, 0), (100, 100), (75, 50)]),
    "xMaxYMax slice, tall page: overflows to the left": (
        'width="100mm" height="100mm" viewBox="0 0 200 100" preserveAspectRatio="xMaxYMax slice"',
        [(0, 100), (200, 0), (100, 50)], [(-100, 0), (100, 100), (0, 50)]),
    "xMinYMin slice, wide page: overflows below": (
        'width="200mm" height="50mm" viewBox="0 0 100 100" preserveAspectRatio="xMinYMin slice"',
        [(0, 100), (100, 0), (50, 50)], [(0, -150), (200, 50), (100, -50)]),
    "xMidYMid slice, wide page: overflows both ways": (
        'width="200mm" height="50mm" viewBox="0 0 100 100" preserveAspectRatio="xMidYMid slice"',
        [(0, 100), (100, 0), (50, 50)], [(0, -75), (200, 125), (100, 25)]),
    "none: each axis stretched on its own": (
        'width="100mm" height="100mm" viewBox="0 0 200 50" preserveAspectRatio="none"',
        [(0, 50), (200, 0), (100, 25)], [(0, 0), (100, 100), (50, 50)]),
    "none ignores slice": (
        'width="100mm" height="100mm" viewBox="0 0 200 50" preserveAspectRatio="none slice"',
        [(0, 50), (200, 0), (100, 25)], [(0, 0), (100, 100), (50, 50)]),
    "SVG 1.1 defer is ignored outside <image>": (
        'width="200mm" height="50mm" viewBox="0 0 100 100" preserveAspectRatio="defer xMinYMin"',
        [(0, 100), (100, 0), (50, 50)], [(0, 0), (50, 50), (25, 25)]),
}


@pytest.mark.parametrize("attrs, user, expected", VIEWPORTS.values(), ids=VIEWPORTS.keys())
def test_viewport_sizing_and_preserve_aspect_ratio(tmp_path, attrs, user, expected):
    d = "M " + " L ".join(f"{float(x)!r} {float(y)!r}" for x, y in user)
    got = read(write_svg(tmp_path, f'<path d="{d}"/>', attrs))
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("value", ["xmidymid", "XMidYMid", "xMidYMid stretch", "meet", "", "xMidYMid meet slice",
                                   "none none", "xMidYMid,meet", "defer", "xMidYMax meet defer"])
def test_bad_preserve_aspect_ratio_names_file_value_and_choices(tmp_path, value):
    path = write_svg(tmp_path, '<path d="M 0 0 L 1 1"/>',
                     f'width="100mm" height="50mm" viewBox="0 0 100 50" preserveAspectRatio="{value}"')
    with pytest.raises(FoldfabError) as info:
        read(path)
    message = str(info.value)
    assert message.startswith(f"{path}: preserveAspectRatio {value!r} ")
    for choice in ("none", "xMidYMid", "x(Min|Mid|Max)Y(Min|Mid|Max)", "meet or slice"):
        assert choice in message
    assert "\n" not in message


ALIGNMENTS = [f"x{x}Y{y}" for x in ("Min", "Mid", "Max") for y in ("Min", "Mid", "Max")]
vb_origins = st.floats(-500, 500, allow_nan=False, allow_infinity=False)
vb_sizes = st.floats(0.5, 500, allow_nan=False, allow_infinity=False)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(vx=vb_origins, vy=vb_origins, vw=vb_sizes, vh=vb_sizes, width=st.none() | vb_sizes,
       height=st.none() | vb_sizes, align=st.sampled_from([None, "none"] + ALIGNMENTS),
       mode=st.sampled_from(["", " meet", " slice"]))
@example(vx=-3.0, vy=7.0, vw=40.0, vh=10.0, width=30.0, height=30.0, align=None, mode=" slice")  # default: meet
@example(vx=0.0, vy=0.0, vw=10.0, vh=40.0, width=50.0, height=20.0, align=None, mode="")
def test_viewbox_centre_and_fit_follow_the_viewport_rules(tmp_path, vx, vy, vw, vh, width, height, align, mode):
    attrs = f'viewBox="{vx!r} {vy!r} {vw!r} {vh!r}"'
    attrs += f' width="{width!r}mm"' if width is not None else ""
    attrs += f' height="{height!r}mm"' if height is not None else ""
    attrs += f' preserveAspectRatio="{align}{mode}"' if align is not None else ""
    x1, y1 = vx + vw, vy + vh
    corners = [(vx, vy), (x1, vy), (x1, y1), (vx, y1)]
    centre = (vx + vw / 2, vy + vh / 2)
    d = "M " + " L ".join(f"{x!r} {y!r}" for x, y in corners + [centre])
    got = read(write_svg(tmp_path, f'<path d="{d}"/>', attrs))
    assert got.shape == (5, 2)
    # The page: a missing side follows from the viewBox's aspect ratio; both missing, the viewBox in px.
    page_w = width if width is not None else height * vw / vh if height is not None else vw * PX
    page_h = height if height is not None else width * vh / vw if width is not None else vh * PX
    box = got[:4]
    left, right = box[:, 0].min(), box[:, 0].max()
    bottom, top = box[:, 1].min(), box[:, 1].max()
    if align == "none":  # stretched: the viewBox is the page, its centre the page's centre
        tol = 1e-9 * max(page_w, page_h)
        np.testing.assert_allclose(got[4], [page_w / 2, page_h / 2], rtol=0, atol=tol)
        np.testing.assert_allclose([left, right, bottom, top], [0, page_w, 0, page_h], rtol=0, atol=tol)
        return
    slice_ = align is not None and mode == " slice"  # mode is written only with an alignment
    align = align or "xMidYMid"  # the default: xMidYMid meet
    s = max(page_w / vw, page_h / vh) if slice_ else min(page_w / vw, page_h / vh)
    tol = 1e-9 * max(page_w, page_h, s * vw, s * vh)
    # x: xMin puts the viewBox's left edge on the page's, xMid the centres together, xMax the right edges.
    cx = {"Min": s * vw / 2, "Mid": page_w / 2, "Max": page_w - s * vw / 2}[align[1:4]]
    # SVG's y runs down from the page top: YMin puts the viewBox's top edge on the page's top edge.
    cy_down = {"Min": s * vh / 2, "Mid": page_h / 2, "Max": page_h - s * vh / 2}[align[5:8]]
    np.testing.assert_allclose(got[4], [cx, page_h - cy_down], rtol=0, atol=tol)
    # uniform scale: the mapped viewBox is s * (vw, vh)
    np.testing.assert_allclose([right - left, top - bottom], [s * vw, s * vh], rtol=1e-9)
    # it fills the page along one axis at least ...
    assert abs(right - left - page_w) <= tol or abs(top - bottom - page_h) <= tol
    if slice_:  # ... and covers the whole page
        assert left <= tol and right >= page_w - tol and bottom <= tol and top >= page_h - tol
    else:  # ... and fits inside it
        assert left >= -tol and right <= page_w + tol and bottom >= -tol and top <= page_h + tol


# --------------------------------------------------------------------------- transforms

def test_nested_group_transforms(tmp_path):
    body = textwrap.dedent("""\
        <g transform="translate(10,5)">
          <g transform="scale(2)">
            <path id="p" transform="translate(1 0)" d="M 1 1 L 4 1 L 4 3"/>
          </g>
        </g>""")
    got = read(write_svg(tmp_path, body), path="p")
    # path transform first, then scale(2), then translate(10, 5): (x, y) -> (2(x + 1) + 10, 2y + 5)
    user = np.array([[14, 7], [20, 7], [20, 11]], float)
    np.testing.assert_allclose(got, np.column_stack([user[:, 0], 50 - user[:, 1]]), atol=1e-9)


def test_rotation_and_matrix_transforms(tmp_path):
    body = ('<g transform="matrix(1 0 0 1 20 10)"><g transform="rotate(90)">'
            '<path d="M 0 0 L 10 0 L 10 5"/></g></g>')
    got = read(write_svg(tmp_path, body))
    # rotate(90): (x, y) -> (-y, x); then translate (20, 10)
    user = np.array([[20, 10], [20, 20], [15, 20]], float)
    np.testing.assert_allclose(got, np.column_stack([user[:, 0], 50 - user[:, 1]]), atol=1e-9)


# --------------------------------------------------------------------------- straight paths

def test_straight_segments_keep_their_exact_corners(tmp_path):
    # Absolute and relative commands, H/V, and a closing Z: only the corners come back, exactly.
    path = write_svg(tmp_path, '<path d="M 10 40 l 20 0 V 10 h -15 L 12.5 25 Z"/>')
    for kwargs in ({}, {"tolerance": 1e-4}, {"tolerance": 10.0}):
        got = read(path, **kwargs)
        user = np.array([[10, 40], [30, 40], [30, 10], [15, 10], [12.5, 25], [10, 40]], float)
        np.testing.assert_array_equal(got, np.column_stack([user[:, 0], 50 - user[:, 1]]))


def test_polyline_and_line_elements_are_paths_too(tmp_path):
    body = '<polyline points="0,50 10,40 20,50"/><line x1="0" y1="0" x2="5" y2="0"/>'
    path = write_svg(tmp_path, body)
    np.testing.assert_allclose(read(path, path=0), [[0, 0], [10, 10], [20, 0]], atol=1e-12)
    np.testing.assert_allclose(read(path, path=1), [[0, 50], [5, 50]], atol=1e-12)


# --------------------------------------------------------------------------- curves

def dense_mm(d: str, sx: float, sy: float, bottom: float, n: int = 20001) -> np.ndarray:
    """Dense points (mm) along the path ``d``: ``n`` per segment, evenly in each segment's parameter."""
    ts = np.linspace(0.0, 1.0, n)
    z = np.concatenate([seg.poly()(ts) if hasattr(seg, "poly") else np.array([seg.point(t) for t in ts])
                        for seg in parse_path(d)])
    return np.column_stack([z.real * sx, (bottom - z.imag) * sy])


def max_chord_error(poly: np.ndarray, dense: np.ndarray) -> float | None:
    """Largest distance from the curve to the chord that replaces it.

    Every polyline point lies on the curve; each chord stands for the dense points
    between its two end points, found in order along the curve.  A dense point
    given to a neighbouring chord is off by at most a dense step or two, so the
    dense step must stay well below the tolerance checked.  None when a polyline
    point lies where the curve passes more than once (then the chord it ends is
    ambiguous).
    """
    step = float(np.linalg.norm(np.diff(dense, axis=0), axis=1).max())
    dist = np.linalg.norm(dense[None, :, :] - poly[:, None, :], axis=2)
    idx, start = [], 0
    for row in dist:
        near = start + np.flatnonzero(row[start:] <= 2 * step)
        assert len(near), "a polyline point is not on the curve"
        if np.any(np.diff(near) > 1):
            return None
        i = start + int(np.argmin(row[start:near[-1] + 1]))
        idx.append(i)
        start = i
    worst = 0.0
    for k in range(len(poly) - 1):
        q = dense[idx[k]:idx[k + 1] + 1]
        a, b = poly[k], poly[k + 1]
        ab = b - a
        t = np.clip((q - a) @ ab / max(float(ab @ ab), 1e-300), 0.0, 1.0)
        worst = max(worst, float(np.linalg.norm(q - (a + t[:, None] * ab), axis=1).max()))
    return worst


S_CURVE = "M 10 90 C 60 -40, 140 140, 190 10"


@pytest.mark.parametrize("tolerance", [2.0, 0.5, 0.1, 0.03, 0.01])
def test_cubic_sampled_within_tolerance(tmp_path, tolerance):
    path = write_svg(tmp_path, f'<path d="{S_CURVE}"/>', 'width="100mm" height="50mm" viewBox="0 0 200 100"')
    got = read(path, tolerance=tolerance)
    dense = dense_mm(S_CURVE, 0.5, 0.5, 100.0, n=100001)
    assert max_chord_error(got, dense) <= tolerance
    np.testing.assert_allclose(got[0], dense[0], atol=1e-12)
    np.testing.assert_allclose(got[-1], dense[-1], atol=1e-12)


# Curves whose pieces bulge past the ends of their chord: measuring the error as the distance to
# the chord's infinite line, or at a few points only, lets them through at up to 1.8 x the tolerance.
BULGING = ["M 166 67 C 61 59, 176 85, 101 59", "M 101 48 C 71 35, 108 62, 122 46",
           "M 41 67 C 87 19, 21 67, 59 50", "M 181 92 C 55 65, 10 7, 102 88",
           "M 147 59 C 171 90, 192 57, 35 25"]


@pytest.mark.parametrize("d", BULGING)
@pytest.mark.parametrize("tolerance", [2.0, 0.5])
def test_curves_bulging_past_the_chord_ends_stay_within_tolerance(tmp_path, d, tolerance):
    path = write_svg(tmp_path, f'<path d="{d}"/>', 'width="100mm" height="50mm" viewBox="0 0 200 100"')
    dense = dense_mm(d, 0.5, 0.5, 100.0, n=40001)
    error = max_chord_error(read(path, tolerance=tolerance), dense)
    assert error is not None and error <= tolerance


@pytest.mark.parametrize("d", ["M 10 50 C 90 -20, 90 120, 10 50", "M 0 0 C 90 -20, 90 120, 0 1e-170",
                               "M 0 0 C 90 0, 90 0, 0 1e-170", "M 0 0 C 0 90, 0 90, 1e-200 0"])
def test_curve_ending_at_or_next_to_its_start(tmp_path, d):
    # The chord of the whole curve has zero or a vanishing length (its square underflows to 0).
    path = write_svg(tmp_path, f'<path d="{d}"/>', 'width="100mm" height="100mm" viewBox="0 0 100 100"')
    got = read(path, tolerance=0.1)
    assert len(got) >= 3  # never the single chord from start to end
    dense = dense_mm(d, 1.0, 1.0, 100.0)
    a, b = got[:-1], got[1:]
    ab = b - a
    t = np.clip(np.einsum("qsi,si->qs", dense[:, None] - a[None], ab) / np.einsum("si,si->s", ab, ab), 0, 1)
    nearest = np.linalg.norm(dense[:, None] - (a[None] + t[..., None] * ab[None]), axis=2).min(axis=1)
    assert nearest.max() <= 0.1


def test_tighter_tolerance_gives_more_points_and_default_is_used(tmp_path):
    path = write_svg(tmp_path, f'<path d="{S_CURVE}"/>', 'width="100mm" height="50mm" viewBox="0 0 200 100"')
    counts = [len(read(path, tolerance=t)) for t in (1.0, 0.1, 0.01)]
    assert counts[0] < counts[1] < counts[2]
    default = read(path)
    dense = dense_mm(S_CURVE, 0.5, 0.5, 100.0)
    assert max_chord_error(default, dense) <= DEFAULT_TOLERANCE
    np.testing.assert_array_equal(default, read(path, tolerance=DEFAULT_TOLERANCE))


def test_tolerance_is_in_mm_under_a_non_uniform_scale(tmp_path):
    # preserveAspectRatio="none": 0.5 mm per unit across, 2 mm per unit up; the tolerance is in mm
    # both ways, so the stretched direction decides how finely the curve is cut.
    attrs = 'width="100mm" height="100mm" viewBox="0 0 200 50" preserveAspectRatio="none"'
    d = "M 10 45 C 60 -10, 140 60, 190 5"
    path = write_svg(tmp_path, f'<path d="{d}"/>', attrs)
    dense = dense_mm(d, 0.5, 2.0, 50.0)
    for tolerance in (1.0, 0.2, 0.05):
        assert max_chord_error(read(path, tolerance=tolerance), dense) <= tolerance


def test_quadratic_and_arc_within_tolerance(tmp_path):
    d = "M 10 40 Q 50 -20 90 40 A 30 20 0 0 1 150 40"
    path = write_svg(tmp_path, f'<path d="{d}"/>', 'width="160mm" height="50mm" viewBox="0 0 160 50"')
    dense = dense_mm(d, 1.0, 1.0, 50.0)
    for tolerance in (0.5, 0.05):
        got = read(path, tolerance=tolerance)
        assert max_chord_error(got, dense) <= tolerance
        # the junction between the two segments is kept exactly
        assert np.min(np.linalg.norm(got - [90, 10], axis=1)) < 1e-9


cubic_coords = st.floats(0, 100, allow_nan=False, allow_infinity=False)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(pts=st.lists(st.tuples(cubic_coords, cubic_coords), min_size=4, max_size=4),
       tolerance=st.sampled_from([3.0, 0.7, 0.1]))
def test_random_cubics_within_tolerance(tmp_path, pts, tolerance):
    flat = [c for p in pts for c in p]
    d = "M {!r} {!r} C {!r} {!r}, {!r} {!r}, {!r} {!r}".format(*flat)
    path = write_svg(tmp_path, f'<path d="{d}"/>', 'width="50mm" height="50mm" viewBox="0 0 100 100"')
    got = read(path, tolerance=tolerance)
    dense = dense_mm(d, 0.5, 0.5, 100.0, n=20001)
    error = max_chord_error(got, dense)
    assume(error is not None)  # the curve runs over itself at a polyline point: no single chord to measure
    assert error <= tolerance


@pytest.mark.parametrize("samples", [2, 3, 17, 60])
def test_samples_gives_exactly_n_points_evenly_spaced(tmp_path, samples):
    d = "M 10 90 C 20 0, 60 0, 100 50 S 180 100, 190 10"  # curvature varies a lot: t is far from arc length
    path = write_svg(tmp_path, f'<path d="{d}"/>', 'width="100mm" height="50mm" viewBox="0 0 200 100"')
    got = read(path, samples=samples)
    assert got.shape == (samples, 2)
    dense = dense_mm(d, 0.5, 0.5, 100.0, n=40001)
    np.testing.assert_allclose(got[0], dense[0], atol=1e-9)
    np.testing.assert_allclose(got[-1], dense[-1], atol=1e-9)
    # arc length of each sample along the dense curve
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))])
    at, start = [], 0
    for p in got:
        i = start + int(np.argmin(np.linalg.norm(dense[start:] - p, axis=1)))
        at.append(arc[i])
        start = i
    steps = np.diff(at)
    np.testing.assert_allclose(steps, arc[-1] / (samples - 1), rtol=0.02)


coordinate = st.integers(0, 200)


@settings(max_examples=25, deadline=None)
@given(points=st.lists(st.tuples(coordinate, coordinate), min_size=7, max_size=7),
       arc=st.booleans(), samples=st.integers(2, 12))
def test_samples_lie_where_svgpathtools_measures_the_arc(tmp_path_factory, points, arc, samples):
    """Each sample sits at its share of the arc length as svgpathtools integrates it (scipy's quad)."""
    (x0, y0), (x1, y1), (x2, y2), (x3, y3), (x4, y4), (rx, ry), (x5, y5) = points
    assume((x4, y4) != (x5, y5))  # svgpathtools refuses an arc that ends where it starts
    tail = f"A {rx + 5} {ry + 5} 30 0 1 {x5} {y5}" if arc else f"Q {rx} {ry} {x5} {y5}"
    d = f"M {x0} {y0} C {x1} {y1} {x2} {y2} {x3} {y3} L {x4} {y4} {tail}"
    path = parse_path(d)
    assume(all(seg.length() > 1 for seg in path) and abs(path.end - path.start) > 1)
    svg = write_svg(tmp_path_factory.mktemp("svg"), f'<path d="{d}"/>',
                    'width="100mm" height="50mm" viewBox="0 0 200 100"')
    got = read(svg, samples=samples)
    total = path.length()
    try:
        expected = [path.point(path.ilength(s)) for s in np.linspace(0, total, samples)[1:-1]]
    except Exception as exc:  # the oracle's own bisection over its quad lengths may not converge
        assume("Maximum iterations reached" not in str(exc))
        raise
    expected = [path.start, *expected, path.end]
    want = np.column_stack([np.real(expected) * 0.5, (100 - np.imag(expected)) * 0.5])
    assume(np.linalg.norm(np.diff(want, axis=0), axis=1).min() > 1e-3)  # the reader drops repeated points
    np.testing.assert_allclose(got, want, atol=1e-6 * total)


def test_reading_svg_leaves_scipy_integrate_unloaded_and_svgpathtools_whole():
    """svgpathtools is loaded without scipy.integrate (80-90 ms), yet its own lengths still use quad."""
    code = textwrap.dedent(f"""\
        import sys
        from pathlib import Path
        from foldfab.geometry.svg_input import read_svg_polyline
        read_svg_polyline(Path({str(JOB_FOLDER / "vase-profile.svg")!r}), "profile", samples=50)
        print("scipy.integrate" in sys.modules)
        import svgpathtools
        print(svgpathtools.CubicBezier(0, 100j, 100 + 100j, 100).length(), "scipy.integrate" in sys.modules)
        """)
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True).stdout.split()
    assert out[0] == "False"
    assert float(out[1]) == pytest.approx(CubicBezier(0, 100j, 100 + 100j, 100).length(), abs=1e-9)
    assert out[2] == "True"


def test_samples_ignore_straight_corners_but_keep_the_ends(tmp_path):
    path = write_svg(tmp_path, '<path d="M 0 50 L 40 50 L 40 20"/>')  # length 70 mm
    got = read(path, samples=8)  # every 10 mm along the path
    expected = [[0, 0], [10, 0], [20, 0], [30, 0], [40, 0], [40, 10], [40, 20], [40, 30]]
    np.testing.assert_allclose(got, expected, atol=1e-6)


# --------------------------------------------------------------------------- choosing the path

MANY = textwrap.dedent("""\
    <defs><path id="hidden" d="M 0 0 L 1 1"/></defs>
    <g transform="translate(0 0)"><path id="first" d="M 0 50 L 10 50"/></g>
    <path id="empty" d=""/>
    <path id="second" d="M 0 50 L 20 50"/>
    <path d="M 0 50 L 30 50"/>
    <path id="fourth" d="M 0 50 L 40 50"/>""")


def test_path_by_index_follows_document_order(tmp_path):
    path = write_svg(tmp_path, MANY)
    # paths in <defs> are not drawn and empty paths are skipped
    lengths = [read(path, path=i)[-1, 0] for i in range(4)]
    assert lengths == [10, 20, 30, 40]
    np.testing.assert_array_equal(read(path), read(path, path=0))


def test_path_by_id(tmp_path):
    path = write_svg(tmp_path, MANY)
    np.testing.assert_array_equal(read(path, path="second"), read(path, path=1))
    np.testing.assert_array_equal(read(path, path="fourth"), read(path, path=3))
    np.testing.assert_allclose(read(path, path="first"), [[0, 0], [10, 0]])


def test_unknown_id_lists_available_ids(tmp_path):
    path = write_svg(tmp_path, MANY)
    with pytest.raises(FoldfabError) as info:
        read(path, path="nope", where="job.toml: [profile].path")
    message = str(info.value)
    assert "job.toml: [profile].path" in message and "'nope'" in message
    for name in ("first", "second", "fourth"):
        assert name in message
    assert "\n" not in message


def test_index_out_of_range_gives_the_count(tmp_path):
    path = write_svg(tmp_path, MANY)
    with pytest.raises(FoldfabError, match=r"path index 4 out of range: .* has 4 drawable path"):
        read(path, path=4)


def test_file_without_paths(tmp_path):
    path = write_svg(tmp_path, '<path id="blank" d=""/>')
    with pytest.raises(FoldfabError, match="has 0 drawable path"):
        read(path)
    with pytest.raises(FoldfabError, match="ids there: none"):
        read(path, path="x")


def test_two_subpaths_are_an_error(tmp_path):
    path = write_svg(tmp_path, '<path id="two" d="M 0 0 L 10 0 M 20 0 L 30 0"/>')
    with pytest.raises(FoldfabError, match="subpaths"):
        read(path, path="two")


def test_closed_path_is_one_piece(tmp_path):
    path = write_svg(tmp_path, '<path d="M 0 50 L 10 50 L 10 40 Z"/>')
    np.testing.assert_allclose(read(path), [[0, 0], [10, 0], [10, 10], [0, 0]])


@pytest.mark.parametrize("content, match", [
    ("<svg", "cannot read SVG"),
    (f'<svg {NS} width="10%" height="5mm"><path d="M 0 0 L 1 1"/></svg>', "unsupported SVG length"),
    (f'<svg {NS} width="10mm" height="5mm" viewBox="0 0 10"><path d="M 0 0 L 1 1"/></svg>', "viewBox"),
    (f'<svg {NS} width="10mm" height="5mm" viewBox="0 0 0 5"><path d="M 0 0 L 1 1"/></svg>', "no area"),
    (f'<svg {NS} width="0mm" height="5mm" viewBox="0 0 10 5"><path d="M 0 0 L 1 1"/></svg>',
     "width '0mm' must be greater than 0"),
    (f'<svg {NS} height="-5mm"><path d="M 0 0 L 1 1"/></svg>', "height '-5mm' must be greater than 0"),
    (f'<svg {NS} width="e" height="5mm"><path d="M 0 0 L 1 1"/></svg>', "width: unsupported SVG length 'e'"),
    (f'<svg {NS} width="1e999mm" height="5mm"><path d="M 0 0 L 1 1"/></svg>', "unsupported SVG length '1e999mm'"),
    (f'<svg {NS} viewBox="0 0 inf 70"><path d="M 0 0 L 1 1"/></svg>', "'0 0 inf 70' is not four finite numbers"),
    (f'<svg {NS} viewBox="0 0 nan 70"><path d="M 0 0 L 1 1"/></svg>', "'0 0 nan 70' is not four finite numbers"),
    (f'<svg {NS}><path d="M 0 0 L x y"/></svg>', "cannot read its paths: .*check the d attributes"),
    (f'<svg {NS}><path d="M 0 70 L nan 35 L 0 0"/></svg>', "cannot read its paths"),
    (f'<svg {NS}><path d="M 0 70 L 1e400 35 L 0 0"/></svg>', "has a point that is not a finite number"),
    (f'<svg {NS} width="1000km" height="5mm" viewBox="0 0 1 1"><path d="M 0 0 L 1 1"/></svg>',
     "unsupported SVG length"),
    (f'<svg {NS} width="10000000mm" height="5mm" viewBox="0 0 1 1" preserveAspectRatio="none">'
     '<path d="M 0 0 L 1 1"/></svg>', r"reaches beyond ±1,000,000 mm"),
    (f'<svg {NS}><path d="Z"/></svg>', r"not a finite number \(or none: a Z before any M\?\)"),
    (f'<svg {NS}><path transform="scale(1e300)" d="M 0 0 C 10 0 10 10 0 20"/></svg>', r"reaches beyond ±1,000,000 mm"),
])
def test_unreadable_files(tmp_path, content, match):
    path = tmp_path / "bad.svg"
    path.write_text(content, encoding="utf-8")
    with pytest.raises(FoldfabError, match=match) as info:
        read(path)
    assert "\n" not in str(info.value)


def test_a_huge_transform_of_an_arc_is_an_error_without_warnings(tmp_path):
    path = tmp_path / "huge.svg"
    path.write_text(f'<svg {NS}><path transform="scale(1e300)" d="M 0 0 A 10 10 0 0 1 10 10"/></svg>')
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # numpy's overflow warnings would be lines of their own on stderr
        with pytest.raises(FoldfabError, match="reaches beyond ±1,000,000 mm"):
            read(path)


# --------------------------------------------------------------------------- through a job file


def test_job_profile_from_svg_with_offset(tmp_path):
    write_svg(tmp_path, '<path id="p" d="M 0 50 L 6 40 L 0 30 L 6 20"/>', name="profile.svg")
    job = write_job(tmp_path, """\
        [profile]
        svg = "profile.svg"
        path = "p"
        offset = [-2, 5]
        [trajectory]
        template = "regular"
        corners = 6
        radius = 40
        """)
    pts = profile_points(load_job(job))
    np.testing.assert_allclose(pts, [[-2, 5], [4, 15], [-2, 25], [4, 35]], atol=1e-12)
    design = load_design(job)
    assert design.grid.x.shape[0] == 4


def test_job_trajectory_from_svg(tmp_path):
    # an open zigzag drawn in cm; the trajectory is 2D, lifted to z = 0
    write_svg(tmp_path, '<path d="M 0 5 L 4 3 L 8 5 L 12 3"/>',
              'width="12cm" height="5cm" viewBox="0 0 12 5"', name="path.svg")
    job = write_job(tmp_path, """\
        [profile]
        points = [[0, 0], [3, 10], [0, 20]]
        [trajectory]
        svg = "path.svg"
        samples = 4
        """)
    traj = trajectory_points(load_job(job))
    np.testing.assert_allclose(traj, [[0, 0, 0], [40, 20, 0], [80, 0, 0], [120, 20, 0]], atol=1e-6)
    assert not load_design(job).grid.closed


def test_relative_svg_resolves_against_the_job_folder(tmp_path, monkeypatch):
    folder = tmp_path / "jobs" / "nested"
    write_svg(folder.parent, '<path id="p" d="M 0 50 L 6 40 L 0 30"/>', name="shape.svg")
    job = write_job(folder, """\
        [profile]
        svg = "../shape.svg"
        path = "p"
        [trajectory]
        template = "regular"
        corners = 4
        radius = 30
        """)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    # a decoy with the same relative name next to the working folder must not be read
    (tmp_path / "shape.svg").write_text("not svg", encoding="utf-8")
    monkeypatch.chdir(elsewhere)
    loaded = load_job(job)
    assert loaded.profile.svg.file == (folder.parent / "shape.svg").resolve()
    assert loaded.profile.svg.file.is_absolute()
    np.testing.assert_allclose(profile_points(loaded), [[0, 0], [6, 10], [0, 20]], atol=1e-12)
    # a relative job path, given from another working folder, resolves the same way
    monkeypatch.chdir(tmp_path)
    again = load_job(Path("jobs/nested/job.toml"))
    assert again.profile.svg.file == loaded.profile.svg.file


def test_svg_job_errors_name_the_key(tmp_path):
    write_svg(tmp_path, '<path id="p" d="M 0 50 L 6 40"/>', name="p.svg")
    base = """\
        [profile]
        svg = "{svg}"
        {extra}
        [trajectory]
        template = "regular"
        corners = 4
        radius = 30
        """
    cases = [
        (dict(svg="missing.svg", extra=""), "[profile].svg: file not found"),
        (dict(svg="p.svg", extra="samples = 5\ntolerance = 0.1"), "[profile].samples: give either"),
        (dict(svg="p.svg", extra="path = true"), "[profile].path"),
        (dict(svg="p.svg", extra="path = -1"), "[profile].path: a path index must be 0 or more"),
        (dict(svg="p.svg", extra="samples = 1"), "[profile].samples: must be at least 2"),
        (dict(svg="p.svg", extra="tolerance = 0"), "[profile].tolerance: must be at least 0.001"),
        (dict(svg="p.svg", extra="tolerance = -0.5"), "[profile].tolerance"),
        (dict(svg="p.svg", extra="samples = 2.5"), "[profile].samples: expected a whole number"),
        (dict(svg="p.svg", extra='tolerance = "fine"'), "[profile].tolerance: expected a number"),
        (dict(svg="p.svg", extra="tolerance = nan"), "[profile].tolerance: expected a finite number"),
        (dict(svg="p.svg", extra="tolerance = 1e-300"), "[profile].tolerance: must be at least 0.001"),
        (dict(svg="p.svg", extra="samples = 100000001"), "[profile].samples: must be at most 100000"),
        (dict(svg="p.svg", extra="points = [[0, 0], [1, 1]]"), "[profile]: give either points"),
        (dict(svg="p.svg", extra="colour = 1"), "[profile].colour: unknown key"),
    ]
    for fmt, expected in cases:
        job = write_job(tmp_path, textwrap.dedent(base).format(**fmt))
        with pytest.raises(FoldfabError) as info:
            load_job(job)
        assert expected in str(info.value), (fmt, str(info.value))
        assert str(job) in str(info.value)


def test_svg_design_errors_name_the_job_and_table(tmp_path):
    write_svg(tmp_path, '<path id="p" d="M 0 50 L 6 40"/><path id="q" d="M 0 0 L 1 1"/>', name="p.svg")
    job = write_job(tmp_path, """\
        [profile]
        svg = "p.svg"
        path = "r"
        [trajectory]
        template = "regular"
        corners = 4
        radius = 30
        """)
    with pytest.raises(FoldfabError) as info:
        load_design(job)
    message = str(info.value)
    assert f"{job}: [profile].svg" in message and "p, q" in message


def test_a_trajectory_closed_with_relative_moves_is_closed(tmp_path):
    """Relative moves add up to 1e-15 off the start; the design is the closed one, as with z."""
    moves = "l 20.1 -20.2 l 40.3 0 l 20.1 20.2 l -20.1 20.2 l -40.3 0 l -20.1 -20.2"
    designs = []
    for d in (f"m 10.1 50.3 {moves}", f"M 10.1 50.3 {moves[:moves.rindex('l')]} z"):
        write_svg(tmp_path, f'<path d="{d}"/>', 'width="100mm" height="100mm" viewBox="0 0 100 100"', name="t.svg")
        job = write_job(tmp_path, """\
            [profile]
            points = [[0, 0], [2, 10], [0, 20]]
            [trajectory]
            svg = "t.svg"
            """)
        designs.append(load_design(job))
    relative, with_z = designs
    assert with_z.grid.closed and relative.grid.closed
    assert relative.grid.corners == with_z.grid.corners == 6
