"""The studio's fabrication panel, save check and dry-run stroke order, in Debian's Chromium
(Playwright, headless): a setting changed in the browser ends in the saved TOML and in the
program ``foldfab export`` writes from it; an invalid design is refused (and saved only on
"save anyway"); the stroke slider at step k highlights stroke k.

Like tests/studio/test_studio_browser.py these never skip, and wait for the studio's own
signals (``data-render-count``, ``data-fabrication-count``), never for a fixed time."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import tomllib

import pytest

from foldfab.studio.api import Studio
from foldfab.studio.server import StudioServer
from helpers import JOB_FOLDER
from helpers.http import serving
from helpers.browser import TIMEOUT_MS, colour_at, renders, studio_page, wait_fabrication, wait_render


@pytest.fixture
def folder(tmp_path):
    shutil.copy(JOB_FOLDER / "hexagon-fig8a.toml", tmp_path / "hexagon.toml")
    return tmp_path


@pytest.fixture
def page(browser, folder):
    with serving(StudioServer(Studio(folder, folder / "hexagon.toml"))) as server, \
            studio_page(browser, server.url) as page:
        yield page


def choose_device(page, name: str) -> None:
    before = page.evaluate("Number(document.body.dataset.fabricationCount || 0)")
    page.select_option("#device", name)
    wait_fabrication(page, before)


def test_a_fabrication_setting_ends_in_the_saved_toml_and_the_exported_program(page, folder):
    choose_device(page, "graphtec-ce6000")
    assert page.input_value("#fab-valley-force") == ""
    assert page.get_attribute("#fab-valley-force", "placeholder") == "6", "the profile's default is shown"
    assert page.get_attribute("#fab-valley-force", "max") == "38", "the profile's range"
    estimate = page.inner_text("#fab-estimate")
    before = page.evaluate("Number(document.body.dataset.fabricationCount)")
    page.fill("#fab-valley-force", "9")
    page.fill("#fab-cut-speed", "50")
    wait_fabrication(page, before)
    assert page.evaluate("window.studio.fabrication.answer.tools.valley.force") == 9
    assert page.inner_text("#fab-estimate") != estimate, "a slower cut changes the estimate"
    before = page.evaluate("Number(document.body.dataset.fabricationCount)")
    page.fill("#fab-margin", "25")
    wait_fabrication(page, before)
    sheet = page.evaluate("window.studio.fabrication.answer.sheets[0]")
    (x0, y0), (x1, y1) = sheet["margin_outline"][0], sheet["margin_outline"][2]
    assert abs(abs(x1 - x0) - (297 - 50)) < 1e-6 and abs(abs(y1 - y0) - (210 - 50)) < 1e-6
    # The sheet's outline is drawn (green) on the crease-pattern view at its corner.
    assert colour_at(page, "creases", sheet["outline"][0]) == "green"
    page.fill("#job-path", "saved.toml")
    page.click("#save")
    page.wait_for_function("document.body.dataset.saved")
    saved = folder / "saved.toml"
    table = tomllib.loads(saved.read_text())["fabrication"]
    assert table["layers"] == {"valley": {"force": 9}, "cut": {"speed": 50}} and table["margin"] == 25
    out = folder / "hexagon.hpgl"
    run = subprocess.run([sys.executable, "-m", "foldfab", "export", str(saved), "--device", "graphtec-ce6000",
                          "-o", str(out)], capture_output=True, text=True, timeout=120, cwd=folder)
    assert run.returncode == 0, run.stderr
    program = out.read_text()
    assert "FS9;" in program and "VS5;" in program, "valley force 9, cut speed 5 cm/s"


def test_out_of_range_force_is_refused_in_the_panel(page):
    choose_device(page, "graphtec-ce6000")
    before = page.evaluate("Number(document.body.dataset.fabricationCount)")
    page.fill("#fab-mountain-force", "99")
    wait_fabrication(page, before)
    assert page.evaluate("document.body.dataset.fabrication") == "error"
    assert "[1, 38]" in page.inner_text("#fab-info")
    assert "invalid" in page.get_attribute("#fab-mountain-force", "class")


def test_split_auto_draws_the_pieces_and_print_writes_the_template(page, folder):
    choose_device(page, "graphtec-ce6000")
    before = page.evaluate("Number(document.body.dataset.fabricationCount)")
    page.fill("#fab-scale", "2.5")
    page.select_option("#fab-split", "auto")
    wait_fabrication(page, before)
    sheets = page.evaluate("window.studio.fabrication.answer.sheets")
    assert len(sheets) > 1 and all(s["piece"] for s in sheets)
    assert f"{len(sheets)} sheets" in page.inner_text("#fab-estimate")
    table = page.evaluate("window.studio.job.fabrication")
    assert table["scale"] == 2.5 and table["split"] == "auto"
    page.fill("#job-name", "my vase")
    assert page.input_value("#print-path") == "my-vase.pdf", "the template is named after the job"
    page.click("#print")
    page.wait_for_function("document.body.dataset.printed")
    pdf = folder / "my-vase.pdf"
    assert pdf.read_bytes().startswith(b"%PDF")
    info = subprocess.run(["pdfinfo", str(pdf)], capture_output=True, text=True, timeout=60)
    assert info.returncode == 0 and int(re.search(r"Pages:\s+(\d+)", info.stdout)[1]) >= 2


def test_a_design_foldfab_design_refuses_is_saved_only_anyway(page, folder):
    before = renders(page)
    page.click("#to-polyline")
    wait_render(page, before)
    before = renders(page)
    page.fill("#glue-tab", "0")
    assert wait_render(page, before) == "ok"
    before = renders(page)
    page.uncheck("#closed")
    assert wait_render(page, before) == "ok"
    before = renders(page)
    page.fill("#glue-tab", "5")
    assert wait_render(page, before) == "error"
    assert "glue_tab" in page.evaluate("window.studio.error.error")
    page.fill("#job-path", "open.toml")
    page.click("#save")
    page.wait_for_function("document.querySelector('#file-message').classList.contains('error')")
    assert "refuses" in page.inner_text("#file-message") and "glue_tab" in page.inner_text("#file-message")
    assert not (folder / "open.toml").exists()
    assert page.is_visible("#save-anyway")
    page.click("#save-anyway")
    page.wait_for_function("document.body.dataset.saved")
    text = (folder / "open.toml").read_text()
    assert text.startswith("# saved by foldfab studio although 'foldfab design' refuses it:\n# ")
    assert "glue_tab" in text.splitlines()[1]
    run = subprocess.run([sys.executable, "-m", "foldfab", "design", str(folder / "open.toml")],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 2 and "glue_tab" in run.stderr


def test_the_stroke_slider_highlights_stroke_k(page):
    choose_device(page, "graphtec-ce6000")
    page.click("#preview")
    page.wait_for_function("document.querySelector('#preview-dialog').open && document.body.dataset.dryrunStep === '0'")
    count = page.evaluate("window.studio.dryrun.strokes.starts.length - 1")
    assert count == 28
    for k in (0, 5, count - 1):
        page.fill("#dryrun-step", str(k))
        page.wait_for_function("k => document.body.dataset.dryrunStep === String(k)", arg=k)
        stroke = page.evaluate(f"window.studio.dryrun.stroke({k})")
        (x0, y0), (x1, y1) = stroke[0], stroke[1] if len(stroke) > 1 else stroke[0]
        assert colour_at(page, "dryrun", [(x0 + x1) / 2, (y0 + y1) / 2]) == "orange", f"stroke {k} is highlighted"
        assert page.inner_text("#dryrun-info").startswith(f"stroke {k + 1} of {count}")
    page.fill("#dryrun-step", "0")
    page.click("#dryrun-play")
    page.wait_for_function(f"document.body.dataset.dryrunStep === '{count - 1}'", timeout=TIMEOUT_MS)
    assert page.inner_text("#dryrun-play") == "play", "playing stops at the last stroke"
