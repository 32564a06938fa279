"""The studio in Debian's Chromium through Playwright, for the browser tests: start it, open a
page, wait for the studio's own signals (never a fixed time), read a pixel of a view."""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

import pytest

CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--enable-unsafe-swiftshader"]
TIMEOUT_MS = 30_000
COLOURS = {"green": (46, 125, 50), "orange": (255, 140, 0), "red": (229, 57, 53), "blue": (30, 99, 214)}
"""The colours :func:`pixel` names: the sheet outline, the current stroke, mountain, valley."""


@contextmanager
def launch() -> Iterator:
    """Headless Chromium under Playwright; a missing one fails the test saying what to install."""
    if not CHROMIUM.is_file():
        pytest.fail(f"Chromium not found at {CHROMIUM}: install it (Debian: apt-get install -y chromium)",
                    pytrace=False)
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.fail("Playwright is not installed: pip install playwright", pytrace=False)
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS, timeout=TIMEOUT_MS)
        try:
            yield browser
        finally:
            browser.close()


@contextmanager
def open_studio(browser, url: str, viewport: tuple[int, int] = (1400, 900)) -> Iterator:
    """A page showing the studio at ``url``, its first design drawn; no JavaScript error may occur."""
    context = browser.new_context(viewport={"width": viewport[0], "height": viewport[1]})
    page = context.new_page()
    page.set_default_timeout(TIMEOUT_MS)
    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    try:
        page.goto(url)
        wait_render(page, 0)
        yield page
        assert not errors, f"JavaScript errors: {errors}"
    finally:
        context.close()


def renders(page) -> int:
    return int(page.evaluate("document.body.dataset.renderCount"))


def wait_render(page, before: int) -> str:
    """Wait until a design response newer than ``before`` is drawn and no edit is pending; the status."""
    page.wait_for_function("n => Number(document.body.dataset.renderCount) > n && document.body.dataset.status !== 'busy'"
                           " && !window.studio.inflight", arg=before)
    return page.evaluate("document.body.dataset.status")


def wait_fabrication(page, before: int) -> str:
    """Wait until the fabrication panel has applied an answer after ``before`` and nothing is pending
    (no design edit, no layout request); its state, "ok" or "error"."""
    page.wait_for_function("n => Number(document.body.dataset.fabricationCount || 0) > n && "
                           "document.body.dataset.status !== 'busy' && !window.studio.inflight && "
                           "!window.studio.fabrication.inflight", arg=before)
    return page.evaluate("document.body.dataset.fabrication")


def pixel(page, view: str, point) -> str | None:
    """The :data:`COLOURS` name found within 1 pixel of ``point`` in a canvas: ``view`` "creases"
    (crease-pattern mm) or "dryrun" (sheet mm); None if none of them is there."""
    found = page.evaluate("""([view, point]) => {
        const target = view === "dryrun" ? window.studio.dryrun : window.studio[view].view;
        const canvas = target.canvas, dpr = window.devicePixelRatio || 1;
        const [sx, sy] = view === "dryrun" ? target.toCanvas(...point) : target.toScreen(...point);
        const data = canvas.getContext("2d").getImageData(Math.round(sx * dpr) - 1, Math.round(sy * dpr) - 1, 3, 3).data;
        return Array.from({length: 9}, (_, i) => [data[4 * i], data[4 * i + 1], data[4 * i + 2]]);
    }""", [view, point])
    for name, colour in COLOURS.items():
        if any(all(abs(a - b) <= 40 for a, b in zip(rgb, colour)) for rgb in found):
            return name
    return None
