"""Profile generators: every profile they make is a valid design on its trajectory."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from foldfab.design import build_design, generated_profile, trajectory_points
from foldfab.errors import DesignError
from foldfab.geometry.feasible import Feasible
from foldfab.geometry.profiles import KINDS, arc, generate, sine, smooth, spline
from foldfab.job import job_from_data, toml_text

CURRENT = np.array([[0.0, 0.0], [8.0, 10.0], [0.0, 20.0], [8.0, 30.0], [0.0, 40.0]])


def _job(trajectory: dict, points, offset, tab: float = 0.0) -> dict:
    return {"design": {"name": "generated"}, "profile": {"points": points, "offset": offset},
            "trajectory": trajectory, "crease": {"flat_angle": 1.0, "glue_tab": tab}}


trajectories = st.one_of(
    st.builds(lambda n, r: {"template": "regular", "corners": 2 * n, "radius": r}, st.integers(2, 10), st.floats(15, 150)),
    st.builds(lambda n, r, f: {"template": "star", "points": n, "outer_radius": r,
                               "inner_radius": r * f * max(np.cos(np.pi / n), 0.5)},
              st.integers(2, 8), st.floats(15, 150), st.floats(0.3, 0.8)),
    st.just({"template": "polyline", "points": [[0, 0], [60, 0], [90, 40], [150, 40]]}),   # open
)


@settings(max_examples=80, deadline=None)
@given(trajectories, st.sampled_from(KINDS), st.floats(-80, 80), st.floats(1, 100), st.integers(2, 120),
       st.floats(5, 200), st.floats(-15, 15), st.sampled_from([0.0, 5.0]))
def test_every_generated_profile_passes_the_design_checks(trajectory, kind, amplitude, period, count, height, shift,
                                                          tab):
    offset = [shift, 0.0]
    tab = 0.0 if trajectory["template"] == "polyline" else tab      # open: no glue tab
    job = job_from_data(_job(trajectory, CURRENT.tolist(), offset, tab), Path("generated.toml"))
    try:
        points = generated_profile(job, kind, amplitude=amplitude, period=period, count=count, height=height)
    except DesignError as error:     # a tab longer than the trajectory's first segment can ever be: said so
        assert tab > 0 and "[crease].glue_tab" in str(error)
        untabbed = job_from_data(_job(trajectory, CURRENT.tolist(), offset), Path("generated.toml"))
        assert len(generated_profile(untabbed, kind, amplitude=amplitude, period=period, count=count, height=height))
        return
    assert np.all(np.isfinite(points)) and len(points) >= 2
    if kind in ("sine", "arc"):
        assert np.all(np.diff(points[:, 1]) > 0)
    data = _job(trajectory, points.tolist(), offset, tab)
    build_design(job_from_data(data, Path("generated.toml"), toml_text(data)))   # no error, no penetration


def test_the_shapes():
    wave = sine(3.0, 10.0, 41, 20.0)
    assert wave[:, 0].max() == pytest.approx(3.0) and wave[5] == pytest.approx([3.0, 2.5])
    bulge = arc(4.0, 40.0, 41, 40.0)
    assert bulge[0, 0] == pytest.approx(0) and bulge[-1, 0] == pytest.approx(0) and bulge[20] == pytest.approx([4, 20])
    radius = (20 ** 2 + 4 ** 2) / 8
    assert np.allclose(np.hypot(bulge[:, 0] - (4 - radius), bulge[:, 1] - 20), radius)   # a circle
    curve = spline(CURRENT, 33)
    assert curve[0] == pytest.approx(CURRENT[0]) and curve[-1] == pytest.approx(CURRENT[-1])
    assert min(np.linalg.norm(curve - p, axis=1).min() for p in CURRENT) < 1e-9   # through the points
    assert np.ptp(smooth(CURRENT, 3)[:, 0]) < np.ptp(CURRENT[:, 0])


def test_a_wave_too_wide_for_its_trajectory_is_clamped_to_the_limit():
    region = Feasible.of(trajectory_points(job_from_data(_job({"template": "regular", "corners": 8, "radius": 40.0},
                                                                 CURRENT.tolist(), [0, 0]), Path("j.toml"))))
    points = generate("sine", region, np.zeros(2), CURRENT, amplitude=20, period=10, count=81)
    assert points[:, 0].max() == pytest.approx(6.3405, abs=0.02) and points[:, 0].min() == pytest.approx(-6.3405, abs=0.02)
    with pytest.raises(DesignError, match="unknown kind"):
        generate("zigzag", region, np.zeros(2), CURRENT)
    with pytest.raises(DesignError, match="period must be"):
        generate("sine", region, np.zeros(2), CURRENT, period=0)


def test_a_glue_tab_no_profile_leaves_room_for_is_named():
    data = _job({"template": "regular", "corners": 20, "radius": 15.0}, CURRENT.tolist(), [0, 0], 5.0)
    with pytest.raises(DesignError, match=r"\[crease\].glue_tab: 5 mm is longer"):
        generated_profile(job_from_data(data, Path("g.toml")), "sine", amplitude=0, period=1, count=2, height=5)
