"""The command line on a design split across sheets (issue 20): files per piece, programs and
previews per sheet, one program with a pause per sheet, and plotting it on ``sim://``."""

from __future__ import annotations

import json

import pytest

from foldfab.queue.sqlite import SqliteQueueStore
from helpers import HEXAGON, JOB_FOLDER
from helpers.cli import run

LANTERN = JOB_FOLDER / "lantern-three-sheets.toml"

pytestmark = pytest.mark.usefixtures("state_home")


def test_design_writes_the_whole_design_and_one_file_per_piece(tmp_path, capsys):
    code, out, err = run(capsys, "design", LANTERN, "--svg", tmp_path / "l.svg", "--fold", tmp_path / "l.fold",
                         "--cp", tmp_path / "l.cp", "--mesh", tmp_path / "l.stl", "--json")
    assert code == 0, err
    info = json.loads(out)
    assert info["pieces"] == 3
    assert "pieces       3" in run(capsys, "design", LANTERN)[1]
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == sorted(["l.svg", "l.fold", "l.cp", "l.stl"] + [f"l-{n}.{ext}" for n in (1, 2, 3)
                                                                  for ext in ("svg", "fold", "cp")])
    whole = json.loads((tmp_path / "l.fold").read_text())
    piece = json.loads((tmp_path / "l-2.fold").read_text())
    assert 0 < len(piece["faces_vertices"]) < len(whole["faces_vertices"])


def test_export_writes_one_program_per_sheet(tmp_path, capsys):
    code, out, err = run(capsys, "export", LANTERN, "--device", "hp7475a", "-o", tmp_path / "l.plt", "--json")
    assert code == 0, err
    sheets = json.loads(out)["sheets"]
    assert [s["written"] for s in sheets] == [str(tmp_path / f"l-{n}.plt") for n in (1, 2, 3)]
    assert all((tmp_path / f"l-{n}.plt").read_text().startswith("IN;") for n in (1, 2, 3))
    assert not (tmp_path / "l.plt").exists()


def test_one_program_pauses_between_sheets_and_preview_shows_every_sheet(tmp_path, capsys):
    code, out, err = run(capsys, "export", LANTERN, "--device", "hp7475a", "-o", tmp_path / "l.plt", "--one-program")
    assert code == 0, err
    assert "pause        Load sheet 2 of 3" in out and "pause        Load sheet 3 of 3" in out
    code, out, err = run(capsys, "preview", LANTERN, "--device", "hp7475a", "-o", tmp_path / "p.svg")
    assert code == 0, err
    for n in (1, 2, 3):
        assert "<svg" in (tmp_path / f"p-{n}.svg").read_text()
        assert f"sheet        {n} of 3" in out


def test_split_auto_on_the_command_line(tmp_path, capsys):
    code, out, err = run(capsys, "export", HEXAGON, "--device", "hp7475a", "-o", tmp_path / "h.plt",
                         "--scale", "2.5", "--split", "auto")
    assert code == 0, err
    assert (tmp_path / "h-1.plt").exists() and (tmp_path / "h-2.plt").exists()
    code, out, err = run(capsys, "export", HEXAGON, "--device", "hp7475a", "-o", tmp_path / "w.plt", "--scale", "2.5")
    assert code == 2 and "largest scale that fits" in err


def test_plot_asks_for_each_new_sheet_and_draws_them_all_on_sim(capsys):
    code, out, err = run(capsys, "plot", LANTERN, "--device", "hp7475a", "--port", "sim://?time=instant", "--json")
    assert code == 2 and "pauses 2 time(s)" in err and "Load sheet 2 of 3" in err
    code, out, err = run(capsys, "plot", LANTERN, "--device", "hp7475a", "--port", "sim://?time=instant",
                         "--json", "--yes")
    assert code == 0, err
    events = [json.loads(line) for line in out.splitlines()]
    pauses = [e for e in events if e.get("event") == "pause"]
    assert len(pauses) == 2
    done = [e for e in events if e.get("event") == "done"]
    assert done and done[-1]["strokes_done"] == done[-1]["strokes_total"] > 0
    assert "Load sheet 3 of 3" in err


def test_the_queue_takes_a_split_job_as_one_job_of_several_sheets(tmp_path, capsys):
    queue = tmp_path / "q.sqlite3"
    code, out, err = run(capsys, "queue", "add", LANTERN, "--device", "hp7475a", "--port", "sim://?time=instant",
                         "--queue", queue)
    assert code == 0, err
    store = SqliteQueueStore(queue)
    [job] = store.jobs()
    assert [p.message for p in store.snapshot(job.id).program.pauses][-2:] == [
        "Load sheet 2 of 3 (piece 2), then continue.", "Load sheet 3 of 3 (piece 3), then continue."]
    code, out, err = run(capsys, "queue", "add", HEXAGON, "--device", "hp7475a", "--port", "sim://?time=instant",
                         "--queue", queue, "--scale", "2.5", "--split", "auto")
    assert code == 0, err
    assert any(p.message.startswith("Load sheet 2 of ") for p in store.snapshot(2).program.pauses)


def test_three_a4_sheets_long_export_preview_plot_and_print_as_three_pieces(tmp_path, capsys):
    """Issue 20's "done when": a design three times as long as an A4 sheet exports, previews,
    plots (on sim://) and prints as three pieces with tabs and matched marks, and the pieces
    glued back give the whole crease pattern."""
    import re

    from foldfab.design import load_design
    from foldfab.devices import load_device
    from foldfab.fabrication.layout import reachable
    from foldfab.fabrication.pieces import design_pieces
    from foldfab.fabrication.spec import job_spec
    from helpers.pieces import assert_pieces_rebuild
    from helpers.poppler import pdfinfo, pdftotext

    design = load_design(LANTERN)
    spec = job_spec(design.job)
    assert design.crease_pattern.sheet_size[0] > 2.5 * spec.sheet[0]   # A4 landscape: 297 mm
    pieces = design_pieces(design, spec, *reachable(design, load_device("hp7475a"), spec))   # as export cuts it
    assert len(pieces) == 3 and all(p.marks for p in pieces)
    assert_pieces_rebuild(design.crease_pattern, pieces)

    code, out, err = run(capsys, "export", LANTERN, "--device", "hp7475a", "-o", tmp_path / "l.plt", "--json")
    assert code == 0, err
    sheets = json.loads(out)["sheets"]
    assert len(sheets) == 3 and all((tmp_path / f"l-{n}.plt").read_text().startswith("IN;") for n in (1, 2, 3))
    assert all(s["layers"]["marks"]["drawn_mm"] > 0 and s["layers"]["cut"]["drawn_mm"] > 0 for s in sheets)

    code, out, err = run(capsys, "preview", LANTERN, "--device", "hp7475a", "-o", tmp_path / "p.svg")
    assert code == 0, err
    assert sorted(p.name for p in tmp_path.glob("p*.svg")) == ["p-1.svg", "p-2.svg", "p-3.svg"]
    assert all(f"sheet        {n} of 3" in out for n in (1, 2, 3))

    code, out, err = run(capsys, "plot", LANTERN, "--device", "hp7475a", "--port", "sim://?time=instant",
                         "--json", "--yes")
    assert code == 0, err
    events = [json.loads(line) for line in out.splitlines()]
    assert [e["message"] for e in events if e.get("event") == "pause"] == [
        "Load sheet 2 of 3 (piece 2), then continue.", "Load sheet 3 of 3 (piece 3), then continue."]
    done = [e for e in events if e.get("event") == "done"]
    assert done and done[-1]["strokes_done"] == done[-1]["strokes_total"] > 0

    code, out, err = run(capsys, "print", LANTERN, "-o", tmp_path / "t.pdf", "--json")
    assert code == 0, err
    info = json.loads(out)
    assert info["pieces"] == 3 and pdfinfo(tmp_path / "t.pdf")[0] == info["pages"]
    tabs, edges = {}, {}
    for page in range(2, info["pages"] + 1):
        text = " ".join(pdftotext(tmp_path / "t.pdf", page).split())
        number = int(re.search(r"piece (\d) of 3", text)[1])
        tabs.update((letter, (number, int(other))) for letter, other in re.findall(r"tab (\w+) goes under piece (\d)", text))
        edges.update((letter, (int(other), number))
                     for letter, other in re.findall(r"edge (\w+) takes the tab of piece (\d)", text))
    assert tabs == edges and sorted(tabs) == ["A", "B", "C"]   # every tab meets the edge with its letter
    assert sorted(a for a, _ in tabs.values()) == [1, 2, 3]


def test_each_piece_svg_carries_its_marks_on_a_layer_origami_simulator_skips(tmp_path, capsys):
    import xml.etree.ElementTree as ET

    import numpy as np

    from foldfab.design import load_design
    from foldfab.fabrication.pieces import design_pieces
    from foldfab.fabrication.spec import job_spec
    from foldfab.formats.svg import user_unit

    code, out, err = run(capsys, "design", LANTERN, "--svg", tmp_path / "l.svg")
    assert code == 0, err
    design = load_design(LANTERN)
    spec = job_spec(design.job)
    pieces = design_pieces(design, spec, spec.sheet)
    ns = "{http://www.w3.org/2000/svg}"
    whole = ET.parse(tmp_path / "l.svg").getroot()
    assert {child.tag for child in whole} == {f"{ns}line"}   # the whole design has no marks
    for piece in pieces:
        root = ET.parse(tmp_path / f"l-{piece.number}.svg").getroot()
        # Origami Simulator reads the root's own line elements only: the creases, as before
        assert {child.tag for child in root} == {f"{ns}line", f"{ns}g"}
        lines = [child for child in root if child.tag == f"{ns}line"]
        assert len(lines) == len(piece.crease_pattern.edges)
        [layer] = [child for child in root if child.tag == f"{ns}g"]
        assert layer.get("id") == "marks" and layer.get("{http://www.inkscape.org/namespaces/inkscape}label") == "marks"
        assert layer.get("stroke") == "#000000"
        strokes = [np.array([p.split(",") for p in poly.get("points").split()], float)
                   for poly in layer.iter(f"{ns}polyline")]
        assert len(strokes) == len(piece.marks) > 0
        cp = piece.crease_pattern
        unit, lo, hi = user_unit(cp.vertices), cp.vertices.min(axis=0), cp.vertices.max(axis=0)
        for drawn, mark in zip(strokes, piece.marks):
            np.testing.assert_allclose(drawn, np.column_stack([mark[:, 0] - lo[0], hi[1] - mark[:, 1]]) / unit,
                                       atol=1e-5)
