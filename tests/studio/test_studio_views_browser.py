"""The studio's views in Chromium: designs that stay valid, the feasible band, views that fit, the fold slider."""

from __future__ import annotations

import numpy as np
import pytest

from foldfab.studio.api import NEW_JOB, Studio
from foldfab.studio.server import StudioServer
from helpers.browser import chromium, load_job, pixel, renders, studio_page, wait_render
from helpers.http import serving


@pytest.fixture(scope="module")
def browser():
    with chromium() as browser:
        yield browser


@pytest.fixture
def server(tmp_path):
    with serving(StudioServer(Studio(tmp_path))) as server:   # a new job: NEW_JOB, whose profile reaches u = 8
        yield server


@pytest.fixture
def page(browser, server):
    with studio_page(browser, server.url) as page:
        yield page


def set_param(page, key: str, value) -> str:
    """Type a template parameter as a user does; the status once the design is drawn."""
    before = renders(page)
    page.fill(f"#param-{key}", str(value))
    page.dispatch_event(f"#param-{key}", "change")
    return wait_render(page, before)


def trajectory(page) -> dict:
    return page.evaluate("window.studio.job.trajectory")


def test_template_switches_and_slider_moves_stay_valid(page):
    assert page.evaluate("document.body.dataset.status") == "ok"
    # regular 6 -> 8 corners: u = 8 > 6.341 at radius 40, so the polygon grows just enough
    assert set_param(page, "corners", 8) == "ok"
    assert trajectory(page) == {"template": "regular", "corners": 8, "radius": 50.5}
    assert page.input_value("#param-radius") == "50.5"
    assert "grew the trajectory" in page.inner_text("#file-message")
    # shrinking the radius stops where the profile still fits
    assert set_param(page, "radius", 20) == "ok"
    assert 50 < trajectory(page)["radius"] < 50.5
    # a star: a deep inner radius, not one whose corners turn by a degree
    before = renders(page)
    page.select_option("#template", "star")
    assert wait_render(page, before) == "ok"
    star = trajectory(page)
    assert star["points"] == 4 and star["inner_radius"] < 0.8 * star["outer_radius"] * np.cos(np.pi / 4)
    # the inner radius towards 0.7 x outer (the 40 / 28: corners that turn by 1.2 degrees)
    # stops at the last valid value
    target = round(0.7 * star["outer_radius"], 1)
    assert set_param(page, "inner_radius", target) == "ok"
    assert star["inner_radius"] < trajectory(page)["inner_radius"] < target
    assert "stops at" in page.inner_text("#file-message")
    before = renders(page)
    page.select_option("#template", "regular")
    assert wait_render(page, before) == "ok"


def band_pixels(page, u: float, heights) -> list[bool]:
    """For each height, whether the profile view shows the band's green tint at (u, v)."""
    shaded = []
    for v in heights:
        r, g, b, _ = pixel(page, "profile", (u, v))
        shaded.append(g - r >= 8 and g - b >= 6)
    return shaded


def test_the_feasible_band_is_drawn_up_to_the_limit_the_error_names(page):
    job = {**NEW_JOB, "profile": {"points": [[0.0, 0.0], [3.0, 10.0], [0.0, 20.0]], "offset": [0.0, 0.0]},
           "trajectory": {"template": "regular", "corners": 8, "radius": 40.0}}
    assert load_job(page, job) == "ok"
    limit = 6.3405   # regular 8-gon of radius 40: u <= R·tan(22.5°)·cos(22.5°)... as the error message says
    band = page.evaluate("window.studio.profile.band()")
    assert max(u for u, _ in band) == pytest.approx(limit, abs=1e-3)
    heights = np.linspace(12.3, 17.7, 7)
    assert page.evaluate("window.studio.profile.view.scale") > 8   # 0.6 mm is several pixels
    assert sum(band_pixels(page, limit - 0.6, heights)) >= 5, "inside the limit: shaded"
    assert sum(band_pixels(page, limit + 0.6, heights)) == 0, "beyond the limit: not shaded"
    assert sum(band_pixels(page, -limit + 0.6, heights)) >= 5 and sum(band_pixels(page, -limit - 0.6, heights)) == 0
    # an invalid design keeps the band, so the user sees where the point must go back to
    before = renders(page)
    page.evaluate("window.studio.job.profile.points[1] = [9, 10]; window.studio.edit()")
    assert wait_render(page, before) == "error"
    assert "6.341" in page.evaluate("window.studio.error.error")
    assert sum(band_pixels(page, limit - 0.6, heights)) >= 5 and sum(band_pixels(page, limit + 0.6, heights)) == 0
