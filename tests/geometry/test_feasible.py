"""The feasible region of profile points: the very rule reflect() enforces, as half-planes."""

from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from foldfab.errors import DesignError
from foldfab.geometry import templates
from foldfab.geometry.feasible import Feasible, fit_template
from foldfab.geometry.reflection import reflect

PROFILE = np.array([[0.0, 0.0], [8.0, 10.0], [0.0, 20.0], [8.0, 30.0], [0.0, 40.0]])

trajectories = st.one_of(
    st.builds(lambda n, r: templates.regular(2 * n, r), st.integers(2, 12), st.floats(10, 200)),
    st.tuples(st.integers(2, 8), st.floats(10, 200), st.floats(0.2, 0.95))
    .filter(lambda s: abs(s[2] - np.cos(np.pi / s[0])) > 0.02)   # inner corners on the outer ones' line: no star
    .map(lambda s: templates.star(s[0], s[1], s[1] * s[2])),
)


def _message_limit(error: DesignError) -> float:
    return float(re.search(r"to at (?:most|least) (-?[\d.e+]+) mm", str(error)).group(1))


def test_the_band_is_the_limit_the_error_message_names():
    trajectory = templates.regular(8, 40)
    with pytest.raises(DesignError) as error:
        reflect(PROFILE, trajectory)
    low, high = Feasible.of(trajectory).u_range([10.0])
    assert _message_limit(error.value) == pytest.approx(high[0], rel=1e-3)
    assert high[0] == pytest.approx(6.3405, abs=1e-4) and low[0] == pytest.approx(-6.3405, abs=1e-4)


@settings(max_examples=60, deadline=None)
@given(trajectories, st.lists(st.tuples(st.floats(-100, 100), st.floats(0.5, 20)), min_size=2, max_size=12))
def test_a_clamped_profile_always_builds_and_an_outside_point_never_does(trajectory, steps):
    region = Feasible.of(trajectory)
    points = np.array([[u, v] for u, v in steps])
    points[:, 1] = np.cumsum(points[:, 1])          # heights rise: no repeated points after clamping
    clamped = region.clamp(points)
    assert np.all(region.lengths(clamped) >= -1e-9)
    reflect(clamped, trajectory)                       # no error
    inside = np.all(region.lengths(points) >= 0, axis=1)
    for j in np.flatnonzero(~inside)[:2]:              # a point the region excludes is refused alone
        worst = region.lengths(points[j:j + 1]).min()
        if worst < -1e-6 * max(1.0, np.abs(points).max()):
            with pytest.raises(DesignError, match="meets"):
                reflect(np.array([points[j], points[j] + [0.0, 1.0]]), trajectory)


@settings(max_examples=40, deadline=None)
@given(trajectories)
def test_the_polygon_is_the_region_inside_its_box(trajectory):
    region = Feasible.of(trajectory)
    polygon = region.polygon((-500, -50, 500, 50))
    assert len(polygon) >= 3
    assert np.all(region.lengths(polygon) >= -1e-9)
    low, high = region.u_range([0.0])
    assert polygon[:, 0].max() == pytest.approx(min(high[0], 500)) and polygon[:, 0].min() == pytest.approx(max(low[0], -500))


def test_more_corners_grow_a_regular_template_just_enough():
    params, note = fit_template("regular", {"corners": 8, "radius": 40.0}, PROFILE, "corners")
    assert params["radius"] == 50.5 and "grew" in note
    reflect(PROFILE, templates.regular(8, params["radius"]))
    with pytest.raises(DesignError):
        reflect(PROFILE, templates.regular(8, params["radius"] - 0.5))


def test_a_new_star_gets_a_deep_inner_radius_and_a_size_slider_stops_at_the_limit():
    params, _ = fit_template("star", {"points": 4, "outer_radius": 40.0, "inner_radius": 28.0}, PROFILE)
    assert params["inner_radius"] < 0.7 * 40 * np.cos(np.pi / 4)
    reflect(PROFILE, templates.star(4, params["outer_radius"], params["inner_radius"]))
    moved, note = fit_template("star", {"points": 4, "outer_radius": 40.0, "inner_radius": 28.0}, PROFILE,
                               "inner_radius", 20.0)
    assert 20.0 < moved["inner_radius"] < 28.0 and "stops" in note
    reflect(PROFILE, templates.star(4, 40.0, moved["inner_radius"]))
    with pytest.raises(DesignError):
        reflect(PROFILE, templates.star(4, 40.0, moved["inner_radius"] + 0.01))
    shrunk, _ = fit_template("regular", {"corners": 6, "radius": 20.0}, PROFILE, "radius", 40.0)
    assert shrunk["radius"] == pytest.approx(8 * 2 * np.sqrt(3), abs=2e-3)   # hexagon: u_max = R / (2√3)


def test_what_no_size_can_fix_is_left_as_it_is():
    assert fit_template("regular", {"corners": 7, "radius": 40.0}, PROFILE, "corners") == ({"corners": 7, "radius": 40.0}, "")
    params, note = fit_template("star", {"points": 4, "outer_radius": 40.0, "inner_radius": 28.0}, PROFILE,
                                "points")
    assert params["outer_radius"] == 40.0 and "not grown" in note
