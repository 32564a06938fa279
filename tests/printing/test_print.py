"""`foldfab print`: the template read back with poppler-utils (pdfinfo, pdftotext, pdftoppm),
an independent reader: page count and size, the labels as text, the line conventions and
the 50 mm scale bar measured in pages rendered at 600 dpi."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from foldfab.design import load_design
from foldfab.job import load_job
from foldfab.printing.creases import crease_polylines
from foldfab.printing.marks import SCALE_BAR, SCALE_BAR_HEIGHT
from foldfab.printing.output import template_pieces, write_template
from foldfab.printing.paper import PrintOptions, parse_paper
from foldfab.printing.styles import STYLES
from foldfab.printing.template import build_template
from helpers import HEXAGON, JOBS
from helpers.cli import run, write_job
from helpers.poppler import DPI, pdfinfo, pdftotext, pixel, render, runs

MM = DPI / 25.4
"""Pixels per mm at 600 dpi."""


def options(paper: str = "A4", **kw) -> PrintOptions:
    size, name, turnable = parse_paper(paper)
    return PrintOptions(size, name, turnable, **kw)


@pytest.mark.parametrize("job", JOBS, ids=[j.stem for j in JOBS])
def test_every_job_prints_a_pdf_pdfinfo_reads(job, tmp_path, capsys):
    out = tmp_path / "t.pdf"
    rc, stdout, err = run(capsys, "print", job, "-o", out, "--json")
    assert rc == 0, err
    import json

    info = json.loads(stdout)
    job_scale = load_job(job).fabrication.get("scale", 1.0)
    assert info["scale"] == (1.0 if job_scale == "fit" else job_scale)  # a plotter's "fit" prints at true size
    pages, sizes = pdfinfo(out)
    assert pages == info["pages"] == 1 + sum(rows * cols for rows, cols in info["tiles"])
    a4 = sorted(round(v, 1) for v in (210.0, 297.0))
    assert all(sorted(round(v, 1) for v in size) == a4 for size in sizes)
    assert len(sizes) == pages


@pytest.mark.parametrize("job", JOBS, ids=[j.stem for j in JOBS])
def test_scale_bar_measures_50_mm_at_600_dpi(job, tmp_path):
    design = load_design(job)
    template, [out] = write_template(design, tmp_path / "t.pdf", options())
    for page in (1, len(template.pages)):
        x, y = template.scale_bars[page - 1]
        height = template.pages[page - 1].height
        box = (x - 3.0, y - 1.0, x + SCALE_BAR + 3.0, y + SCALE_BAR_HEIGHT + 1.0)
        image = render(out, page, box, height)
        row = pixel(box, x, y + SCALE_BAR_HEIGHT / 2)[0]
        dark = np.nonzero(image[row].max(axis=1) < 100)[0]
        assert len(dark) and np.all(np.diff(dark) == 1), "the bar is one unbroken run of ink"
        length = (dark[-1] - dark[0] + 1) / MM
        assert abs(length - SCALE_BAR) <= 0.5, f"page {page}: the scale bar measures {length:.3f} mm"


def straight_segment(cp, kind: str, window, min_length: float = 10.0):
    """The longest straight piece (between two vertices) of a ``kind`` crease of crease pattern
    ``cp`` inside ``window``."""
    best, best_length = None, min_length
    for line in crease_polylines(cp, (kind,))[kind]:
        for a, b in zip(line[:-1], line[1:]):
            inside = all(window[0] + 3 < p[0] < window[2] - 3 and window[1] + 3 < p[1] < window[3] - 3 for p in (a, b))
            if inside and np.hypot(*(b - a)) >= best_length:
                best, best_length = (a, b), np.hypot(*(b - a))
    return best


def sample_crease(out: Path, template, cp, kind: str, piece: int = 0):
    """Ink runs (ink?, length in mm) along the middle of the longest straight ``kind`` crease of
    ``cp`` (the crease pattern of piece ``piece``) on its first tile page, 1.5 mm clear of its
    ends (where other creases meet it), and the colours of its inked pixels; None when that
    page has no such crease 10 mm long."""
    tiling = template.tilings[piece]
    segment = straight_segment(cp, kind, tiling.window(0, 0))
    if segment is None:
        return None
    pa, pb = tiling.to_page(np.array(segment), 0, 0)
    box = (min(pa[0], pb[0]) - 1.0, min(pa[1], pb[1]) - 1.0, max(pa[0], pb[0]) + 1.0, max(pa[1], pb[1]) + 1.0)
    image = render(out, template.page_of(piece, 0, 0) + 1, box, template.pages[1].height)
    length = np.hypot(*(pb - pa))
    steps = np.arange(1.5, length - 1.5, 1 / MM)
    points = pa + (pb - pa) / length * steps[:, None]
    rows, cols = zip(*(pixel(box, x, y) for x, y in points.tolist()))
    line = image[np.array(rows), np.array(cols)].astype(int)
    ink = line.min(axis=1) < 200
    found = [(value, n / MM) for value, n in runs(ink)][1:-1]  # the first and last runs are cut short
    return found, line[ink]


def assert_pattern(found, pattern):
    """The runs repeat ``pattern`` (on, off, on, off, ... mm) within 0.15 mm (3.5 pixels: a
    diagonal line is sampled at the nearest pixel), from some phase."""
    assert len(found) >= len(pattern) + 1, found
    first_on = 0 if found[0][0] else 1
    ons = [i for i in range(0, len(pattern), 2)]
    for phase in ons:
        expected = pattern[phase:] + pattern[:phase]
        if all(abs(n - expected[i % len(expected)]) <= 0.15 for i, (_, n) in enumerate(found[first_on:])):
            return
    pytest.fail(f"runs {[(v, round(n, 2)) for v, n in found]} do not follow {pattern}")


STYLE_CASES = [(job, False) for job in JOBS] + [(HEXAGON, True)]


@pytest.mark.parametrize("job, mono", STYLE_CASES, ids=[f"{j.stem}{'-mono' if m else ''}" for j, m in STYLE_CASES])
def test_valley_dashed_mountain_dash_dot_cut_solid(job, mono, tmp_path):
    design = load_design(job)
    template, [out] = write_template(design, tmp_path / "t.pdf", options(mono=mono))
    sampled = {kind: sample_crease(out, template, design.crease_pattern, kind) for kind in "VMB"}
    assert sampled["V"] is not None and sampled["B"] is not None
    colours = {"V": [0, 114, 178], "M": [213, 94, 0]}
    for kind, (found, ink) in ((k, v) for k, v in sampled.items() if v is not None):
        if kind == "B":
            assert found == [], "the cut line is solid: one run of ink"
        else:
            assert_pattern(found, list(STYLES[kind].dash))
        if mono or kind == "B":
            assert len(ink) and ink.max() < 60
        else:  # Okabe-Ito blue and vermillion
            assert np.all(np.abs(ink.mean(axis=0) - colours[kind]) < 30)


def test_every_page_labels_itself(tmp_path, capsys):
    design = load_design(JOBS[0].parent / "star.toml")
    template, [out] = write_template(design, tmp_path / "t.pdf", options())
    pages = len(template.pages)
    assert pages >= 3, "the star job spans two tiles on A4"
    first = " ".join(pdftotext(out, 1).split())
    for label in ("star column", f"page 1 of {pages}", "Fold all valley folds (dashed) first, then the mountain",
                  "50 mm", "valley fold", "mountain fold", "cut", "29 valley, 30 mountain folds"):
        assert label in first, label
    tiling = template.tilings[0]
    for number in range(2, pages + 1):
        text = " ".join(pdftotext(out, number).split())
        col = number - 2
        for label in ("star column", f"page {number} of {pages}", f"row 1 of 1, column {col + 1} of {tiling.cols}",
                      "valley fold", "mountain fold", "cut", "sheet 286.1 x 34.2 mm", "50 mm: measure this bar"):
            assert label in text, (number, label)


def test_svg_pages_are_the_same_drawing(tmp_path, capsys):
    rc, out, err = run(capsys, "print", JOBS[0].parent / "star.toml", "-o", tmp_path / "t.svg", "--flat")
    assert rc == 0, err
    files = sorted(tmp_path.glob("t-*.svg"))
    assert [f.name for f in files] == ["t-1.svg", "t-2.svg", "t-3.svg"]
    ns = "{http://www.w3.org/2000/svg}"
    root = ET.parse(files[1]).getroot()
    assert (root.get("width"), root.get("height")) == ("210mm", "297mm")
    dashes = {p.get("stroke"): p.get("stroke-dasharray") for p in root.iter(f"{ns}path")}
    for kind in "VMF":
        assert dashes[STYLES[kind].color] == " ".join(f"{d:g}" for d in STYLES[kind].dash)
    assert dashes[STYLES["B"].color] is None
    texts = " ".join(t.text for t in root.iter(f"{ns}text"))
    assert "page 2 of 3" in texts and "valley fold" in texts


@pytest.mark.parametrize("args, fragment", [
    (["--paper", "B5"], "--paper 'B5': expected A4, A3, Letter"),
    (["--paper", "[10, 297]"], "--paper '[10, 297]': each side must be from 80"),
    (["--paper", "[nan, 297]"], "--paper '[nan, 297]': each side"),
    (["--paper", "[100, 120]", "--margin", "15"], "--margin 15: leaves less than 60 x 40 mm of the 100 x 120 mm"),
    (["--overlap", "31"], "--overlap 31: expected a number of mm from 0 to 30"),
    (["--scale", "100000"], "pages of A4, more than 1,000; print it at a smaller --scale"),
])
def test_bad_options_are_one_line_errors_and_write_nothing(args, fragment, tmp_path, capsys):
    rc, out, err = run(capsys, "print", HEXAGON, "-o", tmp_path / "t.pdf", *args)
    assert rc == 2 and fragment in err and len(err.strip().splitlines()) == 1, err
    assert list(tmp_path.iterdir()) == []


def test_output_suffix_and_folder_are_checked_first(tmp_path, capsys):
    rc, out, err = run(capsys, "print", HEXAGON, "-o", tmp_path / "t.png")
    assert rc == 2 and "-o" in err and ".pdf, .svg" in err
    rc, out, err = run(capsys, "print", HEXAGON, "-o", tmp_path / "none" / "t.pdf")
    assert rc == 2 and "does not exist" in err


def test_job_scale_is_printed_and_a_larger_scale_takes_more_pages(tmp_path, capsys):
    job = write_job(tmp_path, HEXAGON.read_text().split("[fabrication]")[0] + "\n[fabrication]\nscale = 2.5\n")
    rc, out, err = run(capsys, "print", job, "-o", tmp_path / "big.pdf", "--json")
    assert rc == 0, err
    import json

    big = json.loads(out)
    rc, out, err = run(capsys, "print", job, "-o", tmp_path / "small.pdf", "--json", "--scale", "1")
    small = json.loads(out)
    assert big["scale"] == 2.5 and small["scale"] == 1
    assert big["pages"] > small["pages"]
    assert pdfinfo(tmp_path / "big.pdf")[0] == big["pages"]


def test_flat_creases_only_with_flat(tmp_path, capsys):
    vase = HEXAGON.parent / "vase-svg.toml"
    ns = "{http://www.w3.org/2000/svg}"
    strokes = {}
    for flag in ([], ["--flat"]):
        folder = tmp_path / ("flat" if flag else "plain")
        folder.mkdir()
        rc, out, err = run(capsys, "print", vase, "-o", folder / "t.svg", *flag)
        assert rc == 0, err
        strokes[bool(flag)] = {p.get("stroke") for p in ET.parse(folder / "t-2.svg").getroot().iter(f"{ns}path")}
    assert STYLES["F"].color in strokes[True] and STYLES["F"].color not in strokes[False]
    assert STYLES["V"].color in strokes[False]


@pytest.mark.parametrize("job, note", [
    (HEXAGON, "The glue tab is the strip at the right end"),
    (HEXAGON.parent / "star.toml", "The two ends of the pattern meet when folded"),
])
def test_first_page_says_where_the_glue_tab_goes(job, note, tmp_path):
    template, [out] = write_template(load_design(job), tmp_path / "t.pdf", options())
    assert note in " ".join(pdftotext(out, 1).split())


def test_svg_pages_are_written_all_or_none(tmp_path, capsys):
    (tmp_path / "t-2.svg").mkdir()  # the second page cannot be written
    rc, out, err = run(capsys, "print", HEXAGON, "-o", tmp_path / "t.svg")
    assert rc == 2 and "-o" in err and "cannot write" in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t-2.svg"]


LANTERN = HEXAGON.parent / "lantern-three-sheets.toml"


def test_a_split_job_prints_its_pieces_with_their_tabs_and_letters(tmp_path, capsys):
    out = tmp_path / "l.pdf"
    rc, stdout, err = run(capsys, "print", LANTERN, "-o", out, "--json")
    assert rc == 0, err
    info = json.loads(stdout)
    design = load_design(LANTERN)
    pieces = template_pieces(design, options())
    assert info["pieces"] == len(pieces) == 3
    template = build_template(design, options(), pieces)   # the layout the command printed
    pages, _ = pdfinfo(out)
    assert pages == info["pages"] == len(template.pages) == 1 + sum(rows * cols for rows, cols in info["tiles"])
    first = " ".join(pdftotext(out, 1).split())
    assert "tab A of piece 1 under edge A of piece 2, tab B of piece 2 under edge B of piece 3" in first
    for index, (piece, tiling) in enumerate(zip(pieces, template.tilings)):
        for row in range(tiling.rows):
            for col in range(tiling.cols):
                text = " ".join(pdftotext(out, template.page_of(index, row, col) + 1).split())
                assert f"piece {index + 1} of 3" in text
                for join in piece.joins:
                    assert (f"tab {join.letter} goes under piece" if join.tab else
                            f"edge {join.letter} takes the tab of piece") in text, (index, join.letter)
    # a valley fold of piece 2 where its own page prints it: dashed, in the valley colour
    found, ink = sample_crease(out, template, pieces[1].crease_pattern, "V", piece=1)
    assert_pattern(found, list(STYLES["V"].dash))
    assert np.all(np.abs(ink.mean(axis=0) - [0, 114, 178]) < 30)
    # piece 2's match marks (its number, its tab's and edge's letters) are drawn in black
    tiling = template.tilings[1]
    strokes = [s for s in pieces[1].marks if len(s) > 1]
    assert strokes
    for stroke in strokes[:: max(1, len(strokes) // 6)]:
        a, b = max(zip(stroke[:-1], stroke[1:]), key=lambda ab: np.hypot(*(ab[1] - ab[0])))
        x, y = tiling.to_page(((a + b) / 2)[None], 0, 0)[0]
        box = (x - 1.0, y - 1.0, x + 1.0, y + 1.0)
        image = render(out, template.page_of(1, 0, 0) + 1, box, template.pages[1].height).astype(int)
        r, c = pixel(box, x, y)
        assert image[r - 2:r + 3, c - 2:c + 3].max(axis=-1).min() < 100, "a mark's stroke is inked black"


def test_split_auto_on_the_command_line_fits_the_sheet_or_the_paper(tmp_path, capsys):
    text = LANTERN.read_text().replace('split = "auto"\n', "")
    job = write_job(tmp_path, text)
    whole = json.loads(run(capsys, "print", job, "-o", tmp_path / "w.pdf", "--json")[1])
    assert whole["pieces"] == 1
    split = json.loads(run(capsys, "print", job, "-o", tmp_path / "s.pdf", "--json", "--split", "auto")[1])
    assert split["pieces"] == 3 and len(split["tiles"]) == 3
    assert "piece 3 of 3" in " ".join(pdftotext(tmp_path / "s.pdf", split["pages"]).split())
    no_sheet = write_job(tmp_path, text.replace('sheet = "A4 landscape"\n', ""), "bare.toml")
    rc, out, err = run(capsys, "print", no_sheet, "-o", tmp_path / "p.pdf", "--split", "auto", "--paper", "[500, 297]")
    assert rc == 0, err
    assert "2 pieces of" in out   # fitted to the paper: two halves of 379 mm fit 480 mm
