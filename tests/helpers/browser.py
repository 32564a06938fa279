"""Driving the studio in Debian's Chromium with Playwright: launching, waiting for renders, reading pixels.

Waits are for the studio's own signal (``<body data-render-count>`` grows and ``data-status`` is no
longer ``busy``), never a fixed time, and each has a timeout.
"""

from __future__ import annotations

import contextlib
from pathlib import Path

import pytest

CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--enable-unsafe-swiftshader"]
TIMEOUT_MS = 30_000
COLOURS = {"green": (46, 125, 50), "orange": (255, 140, 0), "red": (229, 57, 53), "blue": (30, 99, 214)}
"""The colours :func:`colour_at` names: the sheet outline, the current stroke, mountain, valley."""


@contextlib.contextmanager
def playwright_started():
    """Playwright's sync API (fails, never skips, when Chromium or Playwright is missing)."""
    if not CHROMIUM.is_file():
        pytest.fail(f"Chromium not found at {CHROMIUM}: install it (Debian: apt-get install -y chromium); "
                    "the studio's browser tests need it and do not skip", pytrace=False)
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.fail("Playwright is not installed: pip install playwright (its own browser download is not "
                    "needed: the tests use /usr/bin/chromium)", pytrace=False)
    with sync_playwright() as playwright:
        yield playwright


def launch(playwright, extra_args: tuple[str, ...] = ()):
    """Debian's Chromium, headless, with WebGL by SwiftShader."""
    return playwright.chromium.launch(executable_path=str(CHROMIUM), args=[*CHROMIUM_ARGS, *extra_args],
                                      timeout=TIMEOUT_MS)


@contextlib.contextmanager
def chromium():
    """A headless Chromium for the block."""
    with playwright_started() as playwright:
        browser = launch(playwright)
        try:
            yield browser
        finally:
            browser.close()


@contextlib.contextmanager
def studio_page(browser, url: str, width: int = 1400, height: int = 900):
    """A page showing the studio at ``url`` once its first design is drawn; JavaScript errors fail the test."""
    context = browser.new_context(viewport={"width": width, "height": height})
    page = context.new_page()
    page.set_default_timeout(TIMEOUT_MS)
    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.goto(url)
    wait_render(page, 0)
    try:
        yield page
        assert not errors, f"JavaScript errors: {errors}"
    finally:
        context.close()


def renders(page) -> int:
    return int(page.evaluate("document.body.dataset.renderCount"))


def wait_render(page, before: int) -> str:
    """Wait until a response newer than ``before`` renders and no edit is pending; the status."""
    page.wait_for_function("n => Number(document.body.dataset.renderCount) > n && document.body.dataset.status !== 'busy'"
                           " && !window.studio.inflight && !window.studio.fitting", arg=before, timeout=TIMEOUT_MS)
    return page.evaluate("document.body.dataset.status")


def load_job(page, job: dict) -> str:
    """Show ``job`` (its tables) as if opened; the status once drawn."""
    before = renders(page)
    page.evaluate("job => window.studio.load(job, window.studio.path, 'test.toml')", job)
    return wait_render(page, before)


def pixel(page, view: str, world: tuple[float, float]) -> list[int]:
    """The RGBA of the canvas of 2D ``view`` (profile, trajectory, creases) at world point ``world``."""
    return page.evaluate("""([view, x, y]) => {
        const v = window.studio[view].view, dpr = window.devicePixelRatio || 1;
        const [sx, sy] = v.toScreen(x, y);
        return Array.from(v.canvas.getContext("2d").getImageData(Math.round(sx * dpr), Math.round(sy * dpr), 1, 1).data);
    }""", [view, *world])


def wait_fabrication(page, before: int) -> str:
    """Wait until the fabrication panel has applied an answer after ``before`` and nothing is pending
    (no design edit, no layout request); its state, "ok" or "error"."""
    page.wait_for_function("n => Number(document.body.dataset.fabricationCount || 0) > n && "
                           "document.body.dataset.status !== 'busy' && !window.studio.inflight && "
                           "!window.studio.fabrication.inflight", arg=before)
    return page.evaluate("document.body.dataset.fabrication")


def colour_at(page, view: str, point) -> str | None:
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
