"""Make the README's studio screenshots: python docs/studio_pictures.py

Starts the studio on the Figure 8 (a) job (in this repository's folder, as
``foldfab studio jobs/hexagon-fig8a.toml`` would) and photographs it in Debian's
Chromium with Playwright (the test extra; ``scripts/test`` installs Chromium):

- docs/img/studio.png: the four views as the job opens, the profile's feasible band shaded;
- docs/img/studio-tools.png: a sine profile from the profile tools (clamped to the band),
  the 3D model half folded with its strain in red;
- docs/img/studio-fabrication.png: the fabrication panel on the Graphtec, the job at scale 2.5
  split across sheets, each sheet's piece on the crease pattern;
- docs/img/studio-dry-run.png: the dry run's stroke slider at stroke 10.

Nothing is saved: the studio only shows the job.
"""

from __future__ import annotations

import threading
from pathlib import Path

from playwright.sync_api import sync_playwright

from foldfab.studio.api import Studio
from foldfab.studio.server import StudioServer

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "docs" / "img"
CHROMIUM = "/usr/bin/chromium"
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader", "--no-first-run"]
DRAWN = ("document.body.dataset.status === 'ok' && !window.studio.inflight && !window.studio.fitting"
         " && document.body.dataset.fold !== 'busy'")


def main() -> None:
    server = StudioServer(Studio(ROOT, ROOT / "jobs" / "hexagon-fig8a.toml"))
    thread = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True)
    thread.start()
    try:
        with sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            page = browser.new_page(viewport={"width": 1400, "height": 900})
            page.set_default_timeout(30_000)
            page.goto(server.url)
            page.wait_for_function("Number(document.body.dataset.renderCount) > 0 && " + DRAWN)
            page.screenshot(path=str(OUT / "studio.png"))
            page.click("#view-profile details.tools summary")
            page.select_option("#gen-kind", "sine")
            page.fill("#gen-amplitude", "9")
            page.fill("#gen-period", "20")
            page.fill("#gen-points", "17")
            count = page.evaluate("Number(document.body.dataset.renderCount)")
            page.click("#gen-make")
            page.wait_for_function(f"Number(document.body.dataset.renderCount) > {count} && " + DRAWN)
            page.fill("#fold", "80")
            page.wait_for_function("document.body.dataset.fold === '0.8'")
            page.screenshot(path=str(OUT / "studio-tools.png"))
            page = browser.new_page(viewport={"width": 1400, "height": 900})
            page.set_default_timeout(30_000)
            page.goto(server.url)
            page.wait_for_function("Number(document.body.dataset.renderCount) > 0 && " + DRAWN)
            fabricated(page, lambda: page.select_option("#device", "graphtec-ce6000"))
            fabricated(page, lambda: (page.fill("#fab-scale", "2.5"), page.select_option("#fab-split", "auto")))
            page.screenshot(path=str(OUT / "studio-fabrication.png"))
            fabricated(page, lambda: (page.fill("#fab-scale", "1"), page.select_option("#fab-split", "")))
            page.click("#preview")
            page.wait_for_function("document.querySelector('#preview-dialog').open && "
                                   "document.body.dataset.dryrunStep === '0'")
            page.fill("#dryrun-step", "10")
            page.wait_for_function("document.body.dataset.dryrunStep === '10'")
            page.screenshot(path=str(OUT / "studio-dry-run.png"))
            browser.close()
    finally:
        server.shutdown()
        server.server_close()
    print(f"wrote studio.png, studio-tools.png, studio-fabrication.png and studio-dry-run.png in {OUT}")


def fabricated(page, change) -> None:
    """Make ``change`` in the fabrication panel and wait until the panel has drawn its answer."""
    before = page.evaluate("Number(document.body.dataset.fabricationCount || 0)")
    change()
    page.wait_for_function("n => Number(document.body.dataset.fabricationCount || 0) > n && "
                           "!window.studio.inflight && !window.studio.fabrication.inflight", arg=before)


if __name__ == "__main__":
    main()
