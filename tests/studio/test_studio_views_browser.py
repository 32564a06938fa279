"""The studio's views in Chromium: designs that stay valid, the feasible band, views that fit, the fold slider."""

from __future__ import annotations

import numpy as np
import pytest

from foldfab.studio.api import NEW_JOB, Studio
from foldfab.studio.server import StudioServer
from helpers.browser import load_job, pixel, renders, studio_page, wait_render
from helpers.http import serving


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


RESIZED = """() => {
    const s = window.studio, same = (c, w) => Math.abs(c.getBoundingClientRect().width - w) < 1;
    return [s.profile.view, s.trajectory.view, s.creases.view].every(v => same(v.canvas, v.width))
        && same(s.model.canvas, s.model.canvas.width / (window.devicePixelRatio || 1));
}"""

EXTREMES = """() => {
    const s = window.studio, shown = s.shown;
    const extremes = (points) => {
        const pick = (key) => points.reduce((a, b) => (key(b) > key(a) ? b : a));
        return [pick(p => p[0]), pick(p => -p[0]), pick(p => p[1]), pick(p => -p[1])];
    };
    const [ou, ov] = s.job.profile.offset;
    const paths = [];
    for (let i = 0; i < shown.paths.length; i += 3) paths.push([shown.paths[i], shown.paths[i + 1]]);
    const [x0, y0, x1, y1] = shown.cpBox;
    const views = {profile: extremes([...s.profilePoints(), [-ou, -ov]]),
                   trajectory: extremes([...s.trajectoryPoints(), ...paths]),
                   creases: [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]};
    const out = {};
    for (const [name, points] of Object.entries(views)) {
        const v = s[name].view, ctx = v.canvas.getContext("2d"), dpr = window.devicePixelRatio || 1;
        out[name] = {size: [v.width, v.height], hint: (() => { const h = v.canvas.parentElement.querySelector(".hint");
                                                              return h ? h.offsetTop : v.height; })(),
            points: points.map(p => {
                const [sx, sy] = v.toScreen(p[0], p[1]);
                let ink = 0;   // pixels darker than the grid within 3 px: the design is drawn there
                for (let dx = -3; dx <= 3; dx++) for (let dy = -3; dy <= 3; dy++) {
                    const [r, g, b] = ctx.getImageData(Math.round((sx + dx) * dpr), Math.round((sy + dy) * dpr), 1, 1).data;
                    if (r + g + b < 3 * 200) ink++;
                }
                return [sx, sy, ink];
            })};
    }
    return out;
}"""

MODEL_PIXELS = """() => {
    const m = window.studio.model, c = m.canvas;
    m.draw();                                  // read the drawing buffer in the same task as the draw
    const copy = document.createElement("canvas");
    copy.width = c.width; copy.height = c.height;
    const ctx = copy.getContext("2d");
    ctx.drawImage(c, 0, 0);
    const data = ctx.getImageData(0, 0, c.width, c.height).data;
    const box = [Infinity, Infinity, -Infinity, -Infinity];
    for (let y = 0; y < c.height; y++) for (let x = 0; x < c.width; x++) {
        const i = 4 * (y * c.width + x);
        if (data[i] + data[i + 1] + data[i + 2] < 3 * 245) {
            box[0] = Math.min(box[0], x); box[1] = Math.min(box[1], y); box[2] = Math.max(box[2], x); box[3] = Math.max(box[3], y);
        }
    }
    return {box, size: [c.width, c.height], ndc: m.screenBox()};
}"""


def check_whole_design(page) -> None:
    page.wait_for_function(RESIZED)
    for name, view in page.evaluate(EXTREMES).items():
        width, height = view["size"]
        for sx, sy, ink in view["points"]:
            assert 2 <= sx <= width - 2 and 2 <= sy <= min(height, view["hint"]) - 2, f"{name}: ({sx}, {sy}) cropped"
            assert ink > 0, f"{name}: nothing drawn at its extreme point ({sx:.0f}, {sy:.0f})"
    model = page.evaluate(MODEL_PIXELS)
    x0, y0, x1, y1 = model["ndc"]
    assert -1 < x0 and x1 < 1 and -1 < y0 and y1 < 1, f"3D model outside its panel: {model['ndc']}"
    assert max(x1 - x0, y1 - y0) > 1.4, f"3D model fills too little of its panel: {model['ndc']}"
    (px0, py0, px1, py1), (w, h) = model["box"], model["size"]
    assert 0 < px0 and px1 < w - 1 and 0 < py0 and py1 < h - 1, f"3D model pixels touch the edge: {model['box']} of {w}x{h}"
    assert max((px1 - px0) / w, (py1 - py0) / h) > 0.7


def test_every_view_shows_its_whole_design_at_1024x700(page):
    page.evaluate("window.studio.job.profile.offset = [-4, 0]; window.studio.syncControls()")
    before = renders(page)
    page.evaluate("window.studio.edit()")
    assert wait_render(page, before) == "ok"
    page.set_viewport_size({"width": 1024, "height": 700})
    check_whole_design(page)
    page.set_viewport_size({"width": 1300, "height": 850})     # and back: the views refit again
    check_whole_design(page)
    assert set_param(page, "corners", 10) == "ok"              # an edit keeps the 3D model fitted
    check_whole_design(page)


def test_labels_hints_and_the_error_box_leave_the_profile_visible(page):
    page.set_viewport_size({"width": 1024, "height": 700})
    page.wait_for_function(RESIZED)
    label = page.evaluate("window.studio.profile.uLabel")
    hint = page.evaluate("""() => { const h = document.querySelector('#view-profile .hint'),
        c = window.studio.profile.view.canvas.getBoundingClientRect(), r = h.getBoundingClientRect();
        return {top: r.top - c.top, left: r.left - c.left, right: r.right - c.left}; }""")
    assert label["y"] + label["h"] <= hint["top"], f"the u label {label} overlaps the hint {hint}"
    before = renders(page)
    page.evaluate("window.studio.job.profile.points[1] = [30, 10]; window.studio.edit()")
    assert wait_render(page, before) == "error"
    box = page.evaluate("document.querySelector('#view-profile .error').getBoundingClientRect().toJSON()")
    assert box["height"] > 10
    lowest = page.evaluate("""() => { const s = window.studio, v = s.profile.view;
        return Math.max(...s.profilePoints().map(p => v.toPage(p[0], p[1])[1])); }""")
    assert lowest + 5 <= box["top"], "the error box covers the lowest profile point"


def test_export_names_follow_the_jobs_name(page):
    assert page.input_value("#export-path") == "untitled.fold"
    page.fill("#job-name", "tall star")
    assert page.input_value("#export-path") == "tall-star.fold"
    before = renders(page)
    page.select_option("#template", "star")
    wait_render(page, before)
    page.select_option("#export-kind", ".glb")
    assert page.input_value("#export-path") == "tall-star.glb"
    page.fill("#export-path", "out/mine.glb")                   # a path the user typed stays theirs
    page.fill("#job-name", "other")
    page.select_option("#export-kind", ".svg")
    assert page.input_value("#export-path") == "out/mine.svg"


def set_fold(page, percent: int) -> None:
    page.fill("#fold", str(percent))    # a range input: fill sets it and fires input
    page.wait_for_function("t => document.body.dataset.fold === String(t)", arg=percent / 100 if percent < 100 else 1)


def shown_positions(page) -> np.ndarray:
    return np.array(page.evaluate("Array.from(window.studio.model.position.array)")).reshape(-1, 3)


def test_the_fold_slider_goes_from_a_flat_sheet_to_the_folded_model(page):
    folded = np.array(page.evaluate("Array.from(window.studio.shown.modelVertices)")).reshape(-1, 3)
    sheet = np.array(page.evaluate("Array.from(window.studio.shown.cpVertices)")).reshape(-1, 2)
    set_fold(page, 0)
    flat = shown_positions(page)
    centred = flat - flat.mean(axis=0)
    assert np.linalg.svd(centred, compute_uv=False)[-1] < 1e-3, "at 0% every vertex lies in one plane"
    pick = np.random.default_rng(1).choice(len(sheet), 12, replace=False)
    for i in pick:                                   # and the sheet is the crease pattern, unstretched
        np.testing.assert_allclose(np.linalg.norm(flat[pick] - flat[i], axis=1),
                                   np.linalg.norm(sheet[pick] - sheet[i], axis=1), atol=1e-3)
    x0, y0, x1, y1 = page.evaluate("window.studio.model.screenBox()")
    assert -1 < x0 and x1 < 1 and -1 < y0 and y1 < 1, "the flat sheet is fitted too"
    set_fold(page, 50)
    assert "strain up to" in page.inner_text("#model-info")
    colours = np.array(page.evaluate("Array.from(window.studio.model.surface.getAttribute('color').array)"))
    assert colours.reshape(-1, 3)[:, 1].min() < 0.9, "strained faces are reddened"
    set_fold(page, 100)
    np.testing.assert_allclose(shown_positions(page), folded, atol=1e-4)
    assert page.evaluate("window.studio.model.surface.getAttribute('color')") is None


def test_profile_generators_make_valid_designs(page):
    job = {**NEW_JOB, "trajectory": {"template": "regular", "corners": 8, "radius": 40.0},
           "profile": {"points": [[0.0, 0.0], [3.0, 10.0], [0.0, 20.0]], "offset": [0.0, 0.0]}}
    assert load_job(page, job) == "ok"
    page.click("#view-profile details.tools summary")
    page.select_option("#gen-kind", "sine")
    page.fill("#gen-amplitude", "20")          # far wider than the octagon allows (u <= 6.34)
    page.fill("#gen-period", "10")
    page.fill("#gen-points", "61")
    before = renders(page)
    page.click("#gen-make")
    assert wait_render(page, before) == "ok"
    points = np.array(page.evaluate("window.studio.job.profile.points"))
    assert len(points) == 61 and points[:, 1].max() == pytest.approx(20.0)
    assert 6.2 < points[:, 0].max() <= 6.3405 and -6.3405 <= points[:, 0].min() < -6.2
    for kind in ("spline", "smooth", "arc"):
        page.select_option("#gen-kind", kind)
        before = renders(page)
        page.click("#gen-make")
        assert wait_render(page, before) == "ok", kind
    assert page.evaluate("window.studio.history.length") >= 5   # each generated profile is an undoable edit
