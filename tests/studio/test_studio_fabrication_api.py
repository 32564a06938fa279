"""The studio's fabrication API in-process: device settings, the layout and estimate as
``foldfab export`` makes them, every [fabrication] field checked as the command line checks it
(hostile values included), saves of designs ``foldfab design`` refuses, the printable template,
and the dry run's strokes read back from the program."""

from __future__ import annotations

import copy
import json
import re
import shutil
import subprocess
import sys
import tomllib

import numpy as np
import pytest

from foldfab.design import build_design
from foldfab.devices import load_device
from foldfab.fabricate import fabricate_sheets
from foldfab.job import job_data, load_job, parse_job
from foldfab.programs.estimate import estimate
from foldfab.programs.interpret import interpret
from foldfab.studio.api import Studio, refusal_comment
from foldfab.studio.wire import unpack
from helpers import JOB_FOLDER


@pytest.fixture
def folder(tmp_path):
    work = tmp_path / "work"
    work.mkdir()
    shutil.copy(JOB_FOLDER / "hexagon-fig8a.toml", work / "hexagon.toml")
    return work


@pytest.fixture
def studio(folder):
    return Studio(folder, folder / "hexagon.toml")


@pytest.fixture
def hexagon(folder):
    return job_data(load_job(folder / "hexagon.toml"))


def call(studio: Studio, path: str, body: dict):
    response = studio.handle("POST", path, json.dumps(body).encode())
    return response.status, json.loads(response.body)


def with_fabrication(job: dict, **table) -> dict:
    job = copy.deepcopy(job)
    job["fabrication"] = {**job.get("fabrication", {}), **table}
    return job


def test_device_settings_have_the_profiles_defaults_ranges_and_media(studio):
    status, cameo = call(studio, "/api/device", {"device": "silhouette-cameo-4"})
    assert status == 200 and cameo["settings"] == ["force", "speed", "passes"]
    device = load_device("silhouette-cameo-4")
    assert cameo["ranges"]["force"] == list(device.limits.force) and cameo["ranges"]["passes"] == [1, 100]
    assert cameo["layers"]["cut"]["force"] == device.layers["cut"].force
    assert [m["name"] for m in cameo["media"]] == list(device.media) and cameo["media"][0]["score"]
    status, grbl = call(studio, "/api/device", {"device": "grbl"})
    assert "force" not in grbl["settings"] and grbl["ranges"]["force"] is None and grbl["media"] == []
    status, laser = call(studio, "/api/device", {"device": "grbl-laser"})
    assert "power" in laser["settings"] and laser["ranges"]["power"] == [0, 1]


@pytest.mark.parametrize("body, message", [
    ({}, "choose a device"),
    ({"device": 5}, "'device' must be a string"),
    ({"device": "x" * 5000}, "longer than 4096"),
    ({"device": "no-such-plotter"}, "no-such-plotter"),
    ({"device": "../../../etc/passwd"}, "passwd"),
])
def test_device_requests_are_checked(studio, body, message):
    status, answer = call(studio, "/api/device", body)
    assert status == 400 and message in answer["error"]


def test_the_layout_and_estimate_are_what_export_makes(studio, hexagon, folder):
    job = with_fabrication(hexagon, margin=20, layers={"cut": {"speed": 50}})
    status, answer = call(studio, "/api/fabrication", {"job": job, "device": "graphtec-ce6000",
                                                       "path": str(folder / "hexagon.toml")})
    assert status == 200, answer
    parsed = parse_job((folder / "hexagon.toml").read_text(), folder / "hexagon.toml")
    design = build_design(job_from(parsed, job))
    device = load_device("graphtec-ce6000")
    [fab] = fabricate_sheets(design, device)
    times = estimate(interpret(fab.program, device, fab.plan.sheet), device)
    assert answer["estimate"]["time_s"] == round(times.total, 1)
    assert answer["estimate"]["program_bytes"] == len(fab.program.text)
    assert answer["tools"]["cut"]["speed"] == 50 and answer["tools"]["valley"]["force"] == device.layers["valley"].force
    [sheet] = answer["sheets"]
    assert sheet["sheet"] == list(fab.plan.sheet) and sheet["piece"] is None
    # The outline is the sheet mapped back onto the crease pattern: its corners land on the sheet's.
    back = fab.placement.apply(np.array([complex(x, y) for x, y in sheet["outline"]]))
    w, h = fab.plan.sheet
    assert np.allclose(back, [0, w, w + 1j * h, 1j * h], atol=1e-3)
    # The design answer's fit places the sheet the same way (the crease view draws it before the layout comes).
    response = studio.handle("POST", "/api/design", json.dumps({"job": job, "device": "graphtec-ce6000"}).encode())
    fit = unpack(response.body)[0]["fit"]
    assert fit["outline"] == sheet["outline"] and fit["margin_outline"] == sheet["margin_outline"]
    # ... and it holds the whole crease pattern inside its margin.
    v = design.crease_pattern.vertices
    xs, ys = [p[0] for p in sheet["margin_outline"]], [p[1] for p in sheet["margin_outline"]]
    assert min(xs) <= v[:, 0].min() and v[:, 0].max() <= max(xs) and min(ys) <= v[:, 1].min() <= v[:, 1].max() <= max(ys)


def job_from(parsed, tables: dict):
    """The job of ``tables`` (the studio's request) read as its saved TOML would be."""
    from foldfab.job import job_from_data, toml_text

    return job_from_data(tables, parsed.path, toml_text(tables))


def test_split_auto_gives_each_sheet_its_piece(studio, hexagon):
    job = with_fabrication(hexagon, scale=2.5, split="auto")
    status, answer = call(studio, "/api/fabrication", {"job": job, "device": "graphtec-ce6000"})
    assert status == 200, answer
    sheets = answer["sheets"]
    assert len(sheets) == 3 and [s["number"] for s in sheets] == [1, 2, 3]
    boxes = np.array([s["piece"] for s in sheets])
    assert np.all(boxes[1:, 0] < boxes[:-1, 2]), "neighbouring pieces meet (the tab overlaps the next one)"
    assert answer["estimate"]["time_s"] == pytest.approx(sum(s["time_s"] for s in sheets), abs=0.2)
    response = studio.handle("POST", "/api/design", json.dumps({"job": job, "device": "graphtec-ce6000"}).encode())
    assert response.status == 200
    assert unpack(response.body)[0]["fit"]["message"] == "split into 3 pieces for graphtec-ce6000: one 297 x 210 mm sheet each"


HOSTILE = [
    ({"margin": -1}, "fabrication.margin", "at least 0"),
    ({"margin": 1e400}, "fabrication.margin", "finite"),
    ({"scale": 0}, "fabrication.scale", "greater than 0"),
    ({"scale": 1e-300}, "fabrication.scale", "larger [fabrication].scale"),
    ({"scale": 1e300}, "fabrication.scale", "fit"),
    ({"scale": True}, "fabrication.scale", "number > 0"),
    ({"sheet": [0, 10]}, "fabrication.sheet", "[width, height]"),
    ({"sheet": [1e400, 5]}, "fabrication.sheet", "[width, height]"),
    ({"sheet": "B5"}, "fabrication.sheet", "A4"),
    ({"strategy": "laser"}, "fabrication.strategy", "expected one of"),
    ({"media": "x" * 3000}, "fabrication.media", "media preset of graphtec-ce6000"),
    ({"media": 5}, "fabrication.media", "string"),
    ({"split": list(range(1, 2000))}, "fabrication.split", "expected \"auto\""),
    ({"split": list(range(1, 500))}, "fabrication.split", "not a cut this design has"),
    ({"split": "maybe"}, "fabrication.split", "expected \"auto\""),
    ({"split_height": [99]}, "fabrication.split_height", "not a cut"),
    ({"layers": {"valley": {"force": 1e9}}}, "fabrication.layers.valley.force", "[1, 38]"),
    ({"layers": {"valley": {"force": "hard"}}}, "fabrication.layers.valley.force", "a number"),
    ({"layers": {"valley": {"passes": 10**30}}}, "fabrication.layers.valley.passes", "from 1 to 100"),
    ({"layers": {"valley": {"speed": -1}}}, "fabrication.layers.valley.speed", "> 0"),
    ({"layers": {"valley": {"speed": 1e400}}}, "fabrication.layers.valley.speed", "> 0"),
    ({"layers": {"cut": {"pen": 99}}}, "fabrication.layers.cut.pen", "[1, 8]"),
    ({"layers": {"cut": {"nope": 1}}}, "fabrication.layers.cut.nope", "unknown key"),
    ({"layers": {"valley": "x"}}, "fabrication.layers.valley", "table of tool settings"),
    ({"layers": {"glue": {}}}, "fabrication.layers.glue", "unknown key"),
    ({"perforate": {"valley": [0.01, 1]}}, "fabrication.perforate.valley", "from 0.1"),
    ({"max_strokes": 1}, "fabrication.max_strokes", "more than the limit"),
    ({"unknown": 1}, "fabrication.unknown", "unknown key"),
]


@pytest.mark.parametrize("table, field, message", HOSTILE, ids=[str(i) for i in range(len(HOSTILE))])
def test_every_fabrication_field_is_checked_as_the_command_line_checks_it(studio, hexagon, folder, table, field,
                                                                           message):
    job = with_fabrication(hexagon, **table)
    body = json.dumps({"job": job, "device": "graphtec-ce6000"}).replace("Infinity", "1e400")
    response = studio.handle("POST", "/api/fabrication", body.encode())
    answer = json.loads(response.body)
    assert response.status == 400 and message in answer["error"], answer
    assert answer["cause"] == {"view": "creases", "field": field}
    # The command line refuses the same table (the studio saves it only "anyway").
    saved = folder / "hostile.toml"
    status, refused = call(studio, "/api/save", {"job": job, "target": str(saved)})
    if status == 200:   # device checks: only export knows the device
        run = subprocess.run([sys.executable, "-m", "foldfab", "export", str(saved), "--device", "graphtec-ce6000",
                              "-o", str(folder / "hostile.hpgl")], capture_output=True, text=True, timeout=120)
        assert run.returncode == 2 and message in run.stderr
    else:
        assert status == 400 and not saved.exists()


def test_a_setting_the_device_lacks_is_a_warning(studio, hexagon):
    job = with_fabrication(hexagon, layers={"valley": {"power": 0.5}})
    status, answer = call(studio, "/api/fabrication", {"job": job, "device": "graphtec-ce6000"})
    assert status == 200 and "power = 0.5 ignored" in answer["warnings"][0]


OPEN_WITH_TAB = {"design": {"name": "open"}, "profile": {"points": [[0, 0], [8, 10], [0, 20]]},
                 "trajectory": {"template": "polyline", "points": [[0, 0], [40, 0], [40, 30]]}, "crease": {"glue_tab": 5}}


def test_a_save_foldfab_design_refuses_is_refused_with_the_reason(studio, folder):
    target = folder / "open.toml"
    status, answer = call(studio, "/api/save", {"job": OPEN_WITH_TAB, "target": str(target)})
    assert status == 400 and answer["error"].startswith("not saved: 'foldfab design' refuses this job: ")
    assert "glue_tab" in answer["refused"] and answer["cause"]["view"] == "creases"
    assert not target.exists()
    status, answer = call(studio, "/api/save", {"job": OPEN_WITH_TAB, "target": str(target), "anyway": True})
    assert status == 200 and "glue_tab" in answer["refused"]
    text = target.read_text()
    first, second = text.splitlines()[:2]
    assert first == "# saved by foldfab studio although 'foldfab design' refuses it:"
    assert second == f"# {answer['refused']}"
    assert job_data(load_job(target)) == answer["job"], "the comment is only a comment"
    run = subprocess.run([sys.executable, "-m", "foldfab", "design", str(target)], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 2 and answer["refused"] in run.stderr


def test_a_valid_save_has_no_comment(studio, hexagon, folder):
    status, answer = call(studio, "/api/save", {"job": hexagon, "target": str(folder / "ok.toml")})
    assert status == 200 and answer["refused"] is None
    assert not (folder / "ok.toml").read_text().startswith("#")


@pytest.mark.parametrize("reason", ["plain", "line\nbreak", "nul\x00bell\x07esc\x1bdel\x7f", "cr\r\nlf", "tab\tok",
                                    "unicode \u2028 ü ✓"])
def test_the_refusal_comment_stays_a_comment(reason):
    text = refusal_comment(reason) + 'x = 1\n'
    assert tomllib.loads(text) == {"x": 1}
    assert all(line.startswith("#") for line in text.splitlines()[:2])


def test_print_writes_the_template_foldfab_print_writes(studio, hexagon, folder):
    status, answer = call(studio, "/api/print", {"job": hexagon, "target": "hexagon.pdf", "paper": "A4"})
    assert status == 200 and answer["pages"] >= 2 and answer["paper"] == "A4"
    pdf = folder / "hexagon.pdf"
    assert pdf.read_bytes().startswith(b"%PDF")
    info = subprocess.run(["pdfinfo", str(pdf)], capture_output=True, text=True, timeout=60)
    assert re.search(r"Pages:\s+(\d+)", info.stdout)[1] == str(answer["pages"])
    status, again = call(studio, "/api/print", {"job": hexagon, "target": "hexagon.pdf"})
    assert status == 409 and again["exists"]
    status, svg = call(studio, "/api/print", {"job": hexagon, "target": "pages.svg", "paper": "Letter"})
    assert status == 200 and len(svg["written"]) == svg["pages"] and svg["paper"] == "Letter"


@pytest.mark.parametrize("body, message", [
    ({"target": "t.pdf", "paper": "A5"}, "expected A4, A3, Letter"),
    ({"target": "t.pdf", "paper": "[10, 10]"}, "from 80"),
    ({"target": "t.pdf", "paper": 4}, "'paper' must be a string"),
    ({"target": "t.docx"}, "expected a file name ending in .pdf, .svg"),
    ({"target": "../outside.pdf"}, "must stay inside"),
    ({"target": "no-folder/t.pdf"}, "does not exist"),
])
def test_print_requests_are_checked(studio, hexagon, folder, body, message):
    status, answer = call(studio, "/api/print", {"job": hexagon, **body})
    assert status in (400, 409) and message in answer["error"]
    assert not list(folder.glob("*.pdf"))


def test_the_dry_run_strokes_are_the_program_read_back(studio, hexagon):
    status, answer = call(studio, "/api/preview", {"job": hexagon, "device": "hp7475a"})
    assert status == 200
    strokes = answer["strokes"]
    design = build_design(load_job(studio.job_path))
    device = load_device("hp7475a")
    [fab] = fabricate_sheets(design, device, one_program=True)
    run = interpret(fab.program, device, fab.plan.sheet)
    assert len(strokes["starts"]) == len(run.strokes) + 1 and len(strokes["points"]) == 2 * strokes["starts"][-1]
    for k in (0, len(run.strokes) // 2, len(run.strokes) - 1):
        points = np.array(strokes["points"][2 * strokes["starts"][k]:2 * strokes["starts"][k + 1]]).reshape(-1, 2)
        assert np.allclose(points, run.strokes[k].points, atol=1e-3)
        assert strokes["layers"][strokes["layer"][k]] == run.strokes[k].layer


def test_a_design_too_large_for_the_studio_is_saved_unchecked(studio, hexagon, folder, monkeypatch):
    import foldfab.studio.api as api

    monkeypatch.setattr(api, "STUDIO_MAX_FACES", 10)   # the hexagon has 32 faces: the command line builds it
    status, answer = call(studio, "/api/save", {"job": hexagon, "target": str(folder / "large.toml")})
    assert status == 200 and answer["refused"] is None
    assert not (folder / "large.toml").read_text().startswith("#")



def test_a_design_over_its_own_face_limit_is_refused_not_saved_unchecked(studio, hexagon, folder):
    """The job's own [design].max_faces binds the command line too: that is a refusal."""
    hexagon["design"]["max_faces"] = 10   # the hexagon has 32 faces
    status, answer = call(studio, "/api/save", {"job": hexagon, "target": str(folder / "own.toml")})
    assert status == 400 and "max_faces" in answer["refused"] and not (folder / "own.toml").exists()
