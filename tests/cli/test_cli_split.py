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
