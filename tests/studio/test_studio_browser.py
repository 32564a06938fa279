"""The studio in a real browser: Playwright driving Debian's Chromium (headless, WebGL by SwiftShader).

These tests never skip: without Chromium or Playwright they fail and say what to install.
They wait for the studio's own signal (``<body data-render-count>`` grows and
``data-status`` is no longer ``busy``), never for a fixed time, and every wait has a timeout.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from foldfab.job import job_data, load_job
from foldfab.studio.api import Studio
from foldfab.studio.server import StudioServer
from helpers import JOB_FOLDER
from helpers.browser import CHROMIUM, CHROMIUM_ARGS, TIMEOUT_MS, launch, playwright_started, renders, studio_page, wait_render
from helpers.http import serving


@pytest.fixture(scope="module")
def playwright():
    """Playwright, once per module (its sync API runs one instance per thread)."""
    with playwright_started() as playwright:
        yield playwright


@pytest.fixture(scope="module")
def browser(playwright):
    chromium = launch(playwright)
    try:
        yield chromium
    finally:
        chromium.close()


@pytest.fixture
def folder(tmp_path):
    shutil.copy(JOB_FOLDER / "hexagon-fig8a.toml", tmp_path / "hexagon.toml")
    return tmp_path


@pytest.fixture
def server(folder):
    with serving(StudioServer(Studio(folder, folder / "hexagon.toml"))) as server:
        yield server


@pytest.fixture
def page(browser, server):
    with studio_page(browser, server.url) as page:
        yield page


def shown(page) -> dict:
    """What the studio shows: summary and the crease pattern and model arrays."""
    return page.evaluate("""() => {
        const s = window.studio.shown;
        return {summary: s.summary, cp: Array.from(s.cpVertices), model: Array.from(s.modelVertices),
                edges: Array.from(s.edges), groups: s.edgeGroups};
    }""")


def set_field(page, selector: str, value) -> None:
    """Type into a field as a user does (fires input and change)."""
    page.fill(selector, str(value))
    page.dispatch_event(selector, "change")


def profile_point_on_page(page, index: int) -> tuple[float, float]:
    return tuple(page.evaluate(f"(() => {{ const v = window.studio.profile.view; "
                               f"return v.toPage(...window.studio.profilePoints()[{index}]); }})()"))


# --------------------------------------------------------------------------------------------


def test_template_loads_in_all_four_views(page):
    first = shown(page)
    assert first["summary"]["corners"] == 6 and first["summary"]["faces"] == 32
    assert "32 faces" in page.inner_text("#cp-info") and "32 faces" in page.inner_text("#model-info")
    before = renders(page)
    page.select_option("#template", "star")   # 3 points: a deep star, grown until the profile fits (issue 24)
    assert wait_render(page, before) == "ok"
    assert page.is_visible("#param-outer_radius") and page.is_visible("#param-inner_radius")
    star_job = page.evaluate("window.studio.job.trajectory")
    assert star_job["template"] == "star" and star_job["points"] == 3 and star_job["outer_radius"] >= 40
    before = renders(page)
    set_field(page, "#offset-u", -4)           # the paper's position adjustment
    assert wait_render(page, before) == "ok"
    star = shown(page)
    assert star["summary"]["corners"] == 6 and star["cp"] != first["cp"]
    assert not page.is_visible("#view-profile .error")


def test_dragging_a_profile_point_updates_every_view_while_dragging(page):
    page.evaluate("""() => {  // count design requests in flight: the studio sends one at a time
        window.maxInflight = 0; let now = 0; const fetch0 = window.fetch;
        window.fetch = async (...a) => {
            const design = String(a[0]).includes('/api/design');
            if (design) { now++; window.maxInflight = Math.max(window.maxInflight, now); }
            try { return await fetch0(...a); } finally { if (design) now--; }
        };
    }""")
    before = shown(page)
    x, y = profile_point_on_page(page, 1)   # point 1 is (8, 10)
    scale = page.evaluate("window.studio.profile.view.scale")  # px per mm
    page.mouse.move(x, y)
    page.mouse.down()
    count = renders(page)
    page.mouse.move(x - 2 * scale, y, steps=4)   # inwards: outwards the 5 mm glue tab soon stops fitting
    # The crease pattern and the model change before the mouse is released.
    page.wait_for_function("w => window.studio.shown.summary.sheet_mm[1] !== w", arg=before["summary"]["sheet_mm"][1])
    during = shown(page)
    assert during["cp"] != before["cp"] and during["model"] != before["model"]
    for step in range(1, 6):
        page.mouse.move(x - (2 + step * 0.25) * scale, y)
    page.mouse.up()
    assert wait_render(page, count) == "ok"
    assert page.evaluate("window.studio.job.profile.points[1]") == [5, 10], "snapped to the 1 mm grid"
    after = shown(page)
    assert after["cp"] != before["cp"] and after["model"] != before["model"]
    assert after["summary"]["sheet_mm"] != before["summary"]["sheet_mm"]
    assert page.evaluate("window.maxInflight") == 1


def test_odd_corners_show_the_error_and_keep_the_last_valid_design(page):
    valid = shown(page)
    before = renders(page)
    set_field(page, "#param-corners", 7)
    assert wait_render(page, before) == "error"
    assert page.evaluate("document.body.dataset.errorView") == "trajectory"
    message = page.inner_text("#view-trajectory .error")
    assert "even number of corners" in message and "7" in message
    assert page.is_visible("#view-trajectory .error")
    assert "invalid" in page.get_attribute("#param-corners", "class")
    assert not page.is_visible("#view-profile .error")
    # The crease pattern and the model still show the last valid design, marked as such.
    assert shown(page) == valid
    assert page.inner_text("#view-creases .stale") == page.inner_text("#view-model .stale") == "last valid design"
    assert "32 faces" in page.inner_text("#model-info")
    assert page.evaluate("window.studio.model.objects.children.length") > 0
    # The trajectory view draws the 7 corners the user asked for.
    assert len(page.evaluate("window.studio.trajectoryPoints()")) == 9
    before = renders(page)
    set_field(page, "#param-corners", 4)
    assert wait_render(page, before) == "ok"
    assert shown(page)["summary"]["corners"] == 4
    assert not page.is_visible("#view-trajectory .error") and not page.is_visible("#view-creases .stale")
    assert not page.is_visible("#view-model .stale")


def test_saved_job_builds_the_crease_pattern_the_studio_showed(page, folder):
    x, y = profile_point_on_page(page, 3)
    scale = page.evaluate("window.studio.profile.view.scale")
    before = renders(page)
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x - 3 * scale, y + 2 * scale, steps=3)
    page.mouse.up()
    wait_render(page, before)
    before = renders(page)
    set_field(page, "#flat-angle", 4)
    wait_render(page, before)
    page.fill("#job-path", "designs/saved.toml")
    page.click("#save")
    page.wait_for_function("document.body.dataset.status === 'error' || "
                           "document.querySelector('#file-message').classList.contains('error')")
    assert "does not exist" in page.inner_text("#file-message"), "a missing folder is refused"
    (folder / "designs").mkdir()
    page.click("#save")
    page.wait_for_function("document.body.dataset.saved")
    saved = Path(page.evaluate("document.body.dataset.saved"))
    assert saved == (folder / "designs" / "saved.toml").resolve()
    wait_render(page, before)
    studio = shown(page)
    out = folder / "saved.fold"
    run = subprocess.run([sys.executable, "-m", "foldfab", "design", str(saved), "--fold", str(out), "--json"],
                         capture_output=True, text=True, timeout=120, cwd=folder)
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)["creases"] == studio["summary"]["creases"]
    fold = json.loads(out.read_text())
    assert _creases(np.array(fold["vertices_coords"]), fold["edges_vertices"], fold["edges_assignment"]) == \
        _studio_creases(studio)


def _creases(vertices: np.ndarray, edges, assignment) -> set:
    """Each crease as (assignment, its end points rounded to 1 µm, in order)."""
    out = set()
    for (a, b), kind in zip(edges, assignment):
        ends = sorted([tuple(np.round(vertices[a], 3)), tuple(np.round(vertices[b], 3))])
        out.add((kind, *ends))
    return out


def _studio_creases(studio: dict) -> set:
    vertices = np.array(studio["cp"], dtype=np.float32).astype(float).reshape(-1, 2)
    edges = np.array(studio["edges"]).reshape(-1, 2)
    kinds = np.empty(len(edges), "<U1")
    for kind, (start, count) in studio["groups"].items():
        kinds[start:start + count] = kind
    return _creases(vertices, edges.tolist(), kinds.tolist())


def trajectory_point_on_page(page, x: float, y: float) -> tuple[float, float]:
    """Page position of a trajectory point, once the layout has settled (two animation
    frames: a hint or error line appearing can move the view between mapping and click)."""
    page.evaluate("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
    return tuple(page.evaluate(f"window.studio.trajectory.view.toPage({x}, {y})"))


def test_free_polyline_trajectory_is_drawn_and_edited(page):
    before = renders(page)
    page.click("#to-polyline")
    assert wait_render(page, before) == "ok"
    assert page.evaluate("window.studio.job.trajectory.template") == "polyline"
    points = page.evaluate("window.studio.job.trajectory.points")
    assert len(points) == 8 and points[0] == points[-1], "the hexagon, closed, from mid-side to mid-side"
    assert page.is_checked("#closed") and not page.is_visible("#to-polyline")
    # Double-click the middle of the side from corner 0 to corner 1: a new point, on a straight line.
    (x0, y0), (x1, y1) = points[1][:2], points[2][:2]
    before = renders(page)
    page.mouse.dblclick(*trajectory_point_on_page(page, (x0 + x1) / 2, (y0 + y1) / 2))
    assert wait_render(page, before) == "ok"
    assert len(page.evaluate("window.studio.job.trajectory.points")) == 9
    assert shown(page)["summary"]["corners"] == 6, "a point without a turn has no mirror"
    # Pull it out: now it is a seventh corner, which cannot close.
    before = renders(page)
    page.mouse.move(*trajectory_point_on_page(page, (x0 + x1) / 2, (y0 + y1) / 2))
    page.mouse.down()
    page.mouse.move(*trajectory_point_on_page(page, (x0 + x1) / 2 + 6, (y0 + y1) / 2 + 4), steps=3)
    page.mouse.up()
    assert wait_render(page, before) == "error"
    assert "even number of corners" in page.inner_text("#view-trajectory .error")
    # Right-click removes it again; Ctrl+Z (on the view) undoes the removal, Ctrl+Shift+Z redoes it.
    moved = page.evaluate("window.studio.job.trajectory.points[2]")
    before = renders(page)
    page.mouse.click(*trajectory_point_on_page(page, *moved[:2]), button="right")
    assert wait_render(page, before) == "ok"
    assert len(page.evaluate("window.studio.job.trajectory.points")) == 8
    before = renders(page)
    page.keyboard.press("Control+z")
    assert wait_render(page, before) == "error"
    before = renders(page)
    page.keyboard.press("Control+Shift+z")
    assert wait_render(page, before) == "ok"
    # Open it: the glue tab has nothing to join now, which the crease view says; without it, fine.
    before = renders(page)
    page.uncheck("#closed")
    assert wait_render(page, before) == "error"
    assert page.evaluate("document.body.dataset.errorView") == "creases"
    assert "this trajectory is open" in page.inner_text("#view-creases .error")
    assert "invalid" in page.get_attribute("#glue-tab", "class")
    before = renders(page)
    set_field(page, "#glue-tab", 0)
    assert wait_render(page, before) == "ok"
    assert shown(page)["summary"]["closed"] is False
    assert len(page.evaluate("window.studio.job.trajectory.points")) == 7


def test_numeric_entry_and_penetration_highlight(page):
    page.click("#view-profile summary")
    row = "#profile-points tr:nth-child(4)"          # header row, then points 0, 1, 2
    before = renders(page)
    page.fill(f"{row} td:nth-child(2) input", "6")
    page.fill(f"{row} td:nth-child(3) input", "2")
    assert wait_render(page, before) == "error"
    assert page.evaluate("window.studio.job.profile.points[2]") == [6, 2]
    assert page.evaluate("document.body.dataset.errorView") == "model"
    assert "penetration" in page.inner_text("#view-model .error")
    assert page.evaluate("window.studio.error.penetrating.length") > 0
    assert page.evaluate("window.studio.model.rejected !== null"), "the intersecting faces are drawn over the last valid model"
    before = renders(page)
    page.check("#allow-penetration")
    assert wait_render(page, before) == "ok"
    assert shown(page)["summary"]["penetrations"] > 0
    assert page.evaluate("window.studio.shown.penetrating.length") > 0
    assert page.evaluate("window.studio.model.objects.children.some((o) => o.material && o.material.color && "
                         "o.material.color.getHex() === 0xe53935)"), "penetrating faces red in 3D"
    assert "penetration" in page.inner_text("#status-text")


def test_device_fit_dry_run_export_and_queue(page, folder, monkeypatch):
    monkeypatch.setenv("FOLDFAB_QUEUE", str(folder / "queue.sqlite3"))
    before = renders(page)
    page.select_option("#device", "grbl")
    assert wait_render(page, before) == "ok"
    assert page.inner_text("#fit-info").startswith("fits grbl")
    page.click("#preview")
    page.wait_for_function("document.querySelector('#preview-dialog').open && "
                           "document.querySelector('#preview-body img') && document.querySelector('#preview-body img').naturalWidth > 0")
    assert "grbl" in page.inner_text("#preview-info")
    page.click("#preview-close")
    page.select_option("#export-kind", ".cp")
    assert page.input_value("#export-path") == "hexagon-relief-Figure-8-a.cp"   # the job's name
    page.click("#export")
    page.wait_for_function("document.querySelector('#file-message').textContent.startsWith('exported')")
    assert (folder / "hexagon-relief-Figure-8-a.cp").read_text().startswith("1 ")
    page.fill("#port", "sim://grbl")
    page.click("#queue")
    page.wait_for_function("document.querySelector('#file-message').textContent.startsWith('queued')")
    assert "queued job 1 on grbl at sim://grbl" in page.inner_text("#file-message")
    assert (folder / "queue.sqlite3").is_file()


def test_drawing_a_new_trajectory(page):
    before = renders(page)
    set_field(page, "#glue-tab", 0)      # an open trajectory has no seam to glue
    wait_render(page, before)
    page.click("#draw")
    assert page.evaluate("window.studio.job.trajectory") == {"template": "polyline", "points": []}
    square = [(-30, -30), (30, -30), (30, 30), (-30, 30)]
    page.mouse.click(*trajectory_point_on_page(page, *square[0]))
    assert page.evaluate("window.studio.job.trajectory.points") == [[-30, -30]]
    for corner in square[1:]:
        before = renders(page)
        page.mouse.click(*trajectory_point_on_page(page, *corner))
        assert wait_render(page, before) == "ok", "an open polyline is a design as soon as it has two points"
    assert shown(page)["summary"]["closed"] is False
    before = renders(page)
    page.mouse.click(*trajectory_point_on_page(page, *square[0]))   # back at the start: closed
    assert wait_render(page, before) == "ok"
    assert page.evaluate("window.studio.job.trajectory.points") == [list(p) for p in square + square[:1]]
    assert not page.evaluate("window.studio.trajectory.drawing") and page.inner_text("#draw") == "draw new"
    summary = shown(page)["summary"]
    assert summary["closed"] is True and summary["corners"] == 4


def ring_pixels(page, view: str, index: int, points: str) -> int:
    """How many pixels of the error red (#c62828) lie on a ring of radius 10 round point
    ``index`` of ``points`` (a JavaScript expression) in the canvas of ``view``."""
    return page.evaluate(f"""() => {{
        const v = window.studio.{view}.view, ctx = v.canvas.getContext("2d"), dpr = window.devicePixelRatio || 1;
        const [sx, sy] = v.toScreen(...{points}[{index}]);
        let red = 0;
        for (let k = 0; k < 64; k++) {{
            const a = 2 * Math.PI * k / 64;
            const [r, g, b] = ctx.getImageData(Math.round((sx + 10 * Math.cos(a)) * dpr),
                                               Math.round((sy + 10 * Math.sin(a)) * dpr), 1, 1).data;
            if (r > 150 && g < 90 && b < 90) red++;
        }}
        return red;
    }}""")


def test_the_profile_point_an_error_blames_is_ringed_in_red(page):
    page.click("#view-profile summary")
    points = "window.studio.profilePoints()"
    assert ring_pixels(page, "profile", 2, points) == 0
    row = "#profile-points tr:nth-child(5)"          # header row, then points 0, 1, 2, 3
    before = renders(page)
    page.fill(f"{row} td:nth-child(2) input", "0")
    page.fill(f"{row} td:nth-child(3) input", "20")  # point 3 onto point 2
    assert wait_render(page, before) == "error"
    assert page.evaluate("window.studio.error.cause") == {"view": "profile", "point": 2}
    page.wait_for_function("window.studio.profile.view.canvas.width > 0")
    page.evaluate("window.studio.profile.view.draw()")
    assert ring_pixels(page, "profile", 2, points) > 32, "a red ring round the point the error names"
    assert ring_pixels(page, "profile", 0, points) < 8   # no ring: at most where the (red) profile line crosses


ATTACK = """async ({token, studio, save}) => {
  const smuggle = (inner) => fetch("/refused", {method: "POST", body: inner, headers: {"Content-Type": "text/plain"}})
    .then(r => r.text()).catch(e => "error: " + e);
  const read = () => fetch("/next").then(r => r.text()).catch(e => "error: " + e);
  const texts = [await read()];
  const host = studio.replace("http://", "");
  const page = `GET / HTTP/1.1\\r\\nHost: ${host}\\r\\n\\r\\n`;
  const body = JSON.stringify(save);
  const write = `POST /api/save HTTP/1.1\\r\\nHost: ${host}\\r\\nOrigin: ${studio}\\r\\nX-Foldfab-Token: ${token}\\r\\n` +
                `Content-Type: application/json\\r\\nContent-Length: ${new TextEncoder().encode(body).length}\\r\\n\\r\\n${body}`;
  for (let i = 0; i < 5; i++) {
    texts.push(await smuggle(page + write));
    texts.push(await read());
  }
  const json = {"Content-Type": "application/json", "X-Foldfab-Token": token};
  const statuses = [];
  for (const url of ["/api/save", studio + "/api/save"]) {
    statuses.push(await fetch(url, {method: "POST", headers: json, body}).then(r => r.status).catch(e => "blocked"));
  }
  statuses.push(await fetch(studio + "/api/save", {method: "POST", mode: "no-cors", body,
                                                   headers: {"Content-Type": "text/plain"}})
                .then(r => r.type).catch(e => "blocked"));
  return {texts, statuses};
}"""


def test_a_page_of_another_origin_cannot_use_the_studio(playwright, folder, server):
    """DNS rebinding: a page served as evil.example, whose name then resolves to 127.0.0.1, tries to read
    the page (and its token) and to save a file: directly, by smuggling requests in refused requests'
    bodies, and, handed the token, by the API itself (refused for its Host, and cross-origin by the
    browser's preflight, which the studio does not answer)."""
    port = server.server_address[1]
    evil = f"http://evil.example:{port}"
    hexagon = job_data(load_job(folder / "hexagon.toml"))
    # The resolver rule is the rebinding; the disabled features are Chromium's own local-network checks
    # (other browsers and older Chromium have none), so that what is tested is the studio's defence.
    rebinding = ["--host-resolver-rules=MAP evil.example 127.0.0.1",
                 "--disable-features=BlockInsecurePrivateNetworkRequests,PrivateNetworkAccessSendPreflights,"
                 "LocalNetworkAccessChecks"]
    chromium = playwright.chromium.launch(executable_path=str(CHROMIUM), timeout=TIMEOUT_MS,
                                          args=[*CHROMIUM_ARGS, *rebinding])
    try:
        page = chromium.new_page()
        page.set_default_timeout(TIMEOUT_MS)
        page.route(f"{evil}/attack.html", lambda route: route.fulfill(
            status=200, content_type="text/html", body="<!DOCTYPE html><title>elsewhere</title>"))
        page.goto(f"{evil}/attack.html")
        result = page.evaluate(ATTACK, {"token": server.token, "studio": f"http://127.0.0.1:{port}",
                                        "save": {"job": hexagon, "target": "rebound.toml"}})
    finally:
        chromium.close()
    assert not any(server.token in text for text in result["texts"]), "the page (and its token) reached evil.example"
    assert "foldfab studio answers only at 127.0.0.1" in result["texts"][0]
    assert result["statuses"][0] == 403, "the token alone does not let another origin save"
    assert result["statuses"][1:] == ["blocked", "opaque"], result["statuses"]
    assert not (folder / "rebound.toml").exists()
