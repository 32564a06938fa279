"""Studio latency, measured in the browser: from an edit to all four views redrawn.

Run by hand:  python benchmarks/bench_studio.py
Needs Chromium at /usr/bin/chromium and Playwright (pip install playwright).  Headless
Chromium draws WebGL with SwiftShader (on the CPU), so a machine with a GPU is faster.

Each edit moves one profile point the way a drag does (the same code path), then waits for
the studio's "rendered" signal.  Figures per design size:

- drawn: edit -> the four views drawn (profile, trajectory and crease canvases, WebGL frame issued);
- frame: edit -> the next animation frame after that (the browser has painted it);
- core:  the server's part (build with penetration check, fit, encoding), inside "drawn";
- drag:  a 2-second mouse drag of the trajectory dot: mouse moves and updates shown per second;
- fabrication: a change in the fabrication panel (the margin, typed, with the scale "fit" so the
  whole layout changes).  views: -> the four views redrawn, the sheet's outline placed on the
  crease pattern among them; estimate: -> then the program made and read back as `foldfab export`
  makes it and the layout and estimate redrawn from it; request: that last request's round trip.
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_design import wavy_design  # noqa: E402  (a sibling benchmark's design generator)

CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--enable-unsafe-swiftshader"]
SIZES = (("paper scale", 51, 20), ("20,000 faces (fine profile)", 1001, 20), ("20,000 faces (many corners)", 201, 100))
EDITS, WARMUP = 40, 5
FAB_EDITS, FAB_WARMUP, FAB_DEVICE = 10, 2, "graphtec-ce6000"

FAB_EDIT = """async (margin) => {
    const studio = window.studio, t0 = performance.now();
    let core = null;
    const post = studio.post.bind(studio);
    studio.post = async (url, body) => {
        const t = performance.now(), r = await post(url, body);
        if (url === "/api/fabrication") core = performance.now() - t;
        return r;
    };
    let views = null;
    window.addEventListener("studio:rendered", () => { views = performance.now() - t0; }, {once: true});
    const done = new Promise((resolve) => window.addEventListener("studio:fabrication", resolve, {once: true}));
    const input = document.querySelector("#fab-margin");
    input.value = String(margin);
    input.dispatchEvent(new Event("input"));
    await done;
    await new Promise((resolve) => requestAnimationFrame(resolve));
    studio.post = post;
    return {views, total: performance.now() - t0, core, status: document.body.dataset.fabrication};
}"""

EDIT = """async ([index, du]) => {
    const studio = window.studio;
    const done = new Promise((resolve) => window.addEventListener("studio:rendered", (e) => resolve(e.detail), {once: true}));
    const point = studio.editableProfile()[index];
    point[0] += du;
    studio.edit();
    studio.profile.render();
    const update = await done;
    await new Promise((resolve) => requestAnimationFrame(() => requestAnimationFrame(resolve)));
    return {drawn: update.drawn, frame: update.frame, core: update.server && update.server.total,
            status: document.body.dataset.status, faces: Number(document.body.dataset.shownFaces)};
}"""


def job_text(points: int, corners: int) -> tuple[str, float]:
    profile, _ = wavy_design(points, corners)
    rows = ", ".join(f"[{u:.9f}, {v:.9f}]" for u, v in profile)
    step = 0.02 * float(abs(profile[:, 0]).max())
    return (f'[profile]\npoints = [{rows}]\n[trajectory]\ntemplate = "regular"\ncorners = {corners}\nradius = 40\n'
            '[fabrication]\nscale = "fit"\n', step)


def summary(values: list[float]) -> str:
    values = sorted(values)
    p90 = values[int(0.9 * (len(values) - 1))]
    return f"median {statistics.median(values):6.1f}  p90 {p90:6.1f}  max {values[-1]:6.1f} ms"


def measure(browser, folder: Path, label: str, points: int, corners: int) -> None:
    text, step = job_text(points, corners)
    job = folder / f"{points}x{corners}.toml"
    job.write_text(text)
    # The server in its own process, as `foldfab studio` runs it (not sharing a GIL with Playwright).
    server = subprocess.Popen([sys.executable, "-m", "foldfab", "studio", job.name, "--no-browser"], cwd=folder,
                              stdout=subprocess.PIPE, text=True)
    url = server.stdout.readline().split()[2]
    page = browser.new_page(viewport={"width": 1400, "height": 900})
    page.set_default_timeout(60_000)
    try:
        page.goto(url)
        page.wait_for_function("Number(document.body.dataset.renderCount) > 0 && document.body.dataset.status === 'ok'")
        index = points // 2
        runs = []
        for i in range(WARMUP + EDITS):
            result = page.evaluate(EDIT, [index, step if i % 2 == 0 else -step])
            if result["status"] != "ok":
                raise SystemExit(f"{label}: the edit made the design invalid: {page.inner_text('#status-text')}")
            if i >= WARMUP:
                runs.append(result)
        faces = runs[-1]["faces"]
        print(f"{label} ({faces:,} faces), {EDITS} edits")
        for key in ("drawn", "frame", "core"):
            print(f"  {key:<6} {summary([r[key] for r in runs])}")
        # Drag the trajectory dot up and down (the profile's height offset: valid for any planar design).
        x, y = page.evaluate("window.studio.profile.view.toPage(...window.studio.job.profile.offset.map((c) => -c))")
        page.evaluate("document.querySelector('#snap').checked = false; window.moves = 0; "
                      "window.studio.profile.view.canvas.addEventListener('pointermove', () => window.moves++)")
        before = int(page.evaluate("document.body.dataset.renderCount"))
        start = page.evaluate("performance.now()")
        page.mouse.move(x, y)
        page.mouse.down()
        for k in range(120):  # about 2 s at 60 moves per second
            page.mouse.move(x, y + (3 if k % 2 else -3))
            page.wait_for_timeout(1000 / 60)
        page.mouse.up()
        page.wait_for_function("document.body.dataset.status !== 'busy' && !window.studio.inflight")
        seconds = (page.evaluate("performance.now()") - start) / 1000
        shown = int(page.evaluate("document.body.dataset.renderCount")) - before
        moves = page.evaluate("window.moves")
        print(f"  drag   {moves / seconds:6.1f} mouse moves/s, {shown / seconds:5.1f} updates shown/s")
        measure_fabrication(page, label)
    finally:
        page.close()
        server.terminate()
        server.wait(timeout=30)


def measure_fabrication(page, label: str) -> None:
    """A fabrication panel change to every view and the estimate redrawn (see the docstring)."""
    page.select_option("#device", FAB_DEVICE)
    page.wait_for_function("Number(document.body.dataset.fabricationCount || 0) > 0 && "
                           "!window.studio.fabrication.inflight")
    runs = []
    for i in range(FAB_WARMUP + FAB_EDITS):
        result = page.evaluate(FAB_EDIT, 10 + i % 2)
        if result["status"] != "ok":
            raise SystemExit(f"{label}: the fabrication failed: {page.inner_text('#fab-info')}")
        if i >= FAB_WARMUP:
            runs.append(result)
    print(f"  fabrication on {FAB_DEVICE} ({page.inner_text('#fab-estimate').strip('· ')}), {FAB_EDITS} changes")
    for key, name in (("views", "views"), ("total", "estimate"), ("core", "request")):
        print(f"    {name:<8} {summary([r[key] for r in runs])}")


def main() -> None:
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory() as tmp, sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_ARGS)
        try:
            print(f"Chromium {browser.version}, WebGL: "
                  + browser.new_page().evaluate("""() => { const gl = document.createElement('canvas').getContext('webgl2');
                        const info = gl.getExtension('WEBGL_debug_renderer_info');
                        return gl.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : gl.RENDERER); }"""))
            for label, points, corners in SIZES:
                measure(browser, Path(tmp), label, points, corners)
        finally:
            browser.close()


if __name__ == "__main__":
    main()
