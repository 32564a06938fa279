"""foldfab export / preview: reports, files, and clear errors with nothing half-written."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from foldfab.cli import main
from foldfab.devices import load_device
from foldfab.programs.interpret import interpret
from helpers import HEXAGON, JOBS, ROOT
from helpers.cli import run



def assert_clean_error(code, out, err, folder: Path, *needles: str):
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("foldfab: error: "), err
    assert "Traceback" not in err
    for needle in needles:
        assert needle in lines[0], lines[0]
    assert list(folder.iterdir()) == [], "an output or temporary file was left behind"


@pytest.mark.parametrize("device, suffix", [("graphtec-ce6000", ".plt"), ("hp7475a", ".hpgl"),
                                            ("roland-gx24", ".plt"), ("grbl", ".gcode")])
def test_export_writes_the_program_and_reports(tmp_path, capsys, device, suffix):
    out_file = tmp_path / f"hex{suffix}"
    code, out, err = run(capsys, "export", HEXAGON, "--device", device, "-o", out_file, "--json")
    assert code == 0, err
    info = json.loads(out)
    assert info["device"] == device and info["strategy"] == "force"
    assert set(info["layers"]) == {"valley", "mountain", "cut"}
    assert info["travel_mm"]["total_after"] <= info["travel_mm"]["total_before"]
    assert {"from park", "between layers", "to park"} <= set(info["travel_mm"]["after"])
    assert info["estimated_time_s"] >= info["lower_bound_s"] > 0
    text = out_file.read_text()
    assert len(text) == info["program_bytes"]
    run_ = interpret(text, load_device(device), tuple(info["sheet_mm"]))
    assert round(sum(s.length for s in run_.strokes), 1) == pytest.approx(
        sum(layer["drawn_mm"] for layer in info["layers"].values()), abs=0.5)


def test_preview_is_drawn_from_the_program(tmp_path, capsys):
    svg = tmp_path / "preview.svg"
    code, out, err = run(capsys, "preview", HEXAGON, "--device", "graphtec-ce6000", "-o", svg)
    assert code == 0, err
    text = svg.read_text()
    assert 'id="sheet"' in text and 'id="plottable-area"' in text
    assert "#ff0000" in text and "#0000ff" in text and "stroke-dasharray" in text
    assert "valley:" in text and "mountain:" in text and "cut:" in text and "total:" in text
    assert "estimate" in out


def test_two_sided_preview_states_the_flip(tmp_path, capsys):
    job = tmp_path / "two.toml"
    job.write_text(HEXAGON.read_text().replace('strategy = "force"', 'strategy = "two-sided"'))
    svg = tmp_path / "preview.svg"
    code, out, err = run(capsys, "preview", job, "--device", "graphtec-ce6000", "-o", svg)
    assert code == 0, err
    import re

    legend = " ".join(" ".join(re.findall(r"<text[^>]*>([^<]*)</text>", svg.read_text())).split())
    assert "Flip the sheet left-right" in legend and "registration corner" in legend
    assert "pause" in out and "Flip the sheet" in out


@pytest.mark.parametrize("args, needles", [
    (["--device", "plotomatic"], ["plotomatic", "graphtec-ce6000"]),                 # unknown device lists known
    (["--device", "{tmp}/broken.toml"], ["broken.toml", "baudrate"]),               # bad profile names file, key
    (["--device", "grbl", "-o", "{tmp}/x.plt"], [".gcode"]),                        # wrong program extension
    (["--device", "graphtec-ce6000", "-o", "{tmp}/nope/x.plt"], ["does not exist"]),  # missing folder
    (["--device", "graphtec-ce6000", "-o", "{tmp}/other/taken.plt"], ["-o", "taken.plt: is a folder"]),
    (["--device", "graphtec-ce6000", "-o", "{tmp}/broken.toml/x.plt"], ["broken.toml is a file, not a folder"]),
    (["--device", "graphtec-ce6000", "-o", "{tmp}/other/full.plt"], ["full.plt: No space left on device"]),
])
def test_export_errors(tmp_path, capsys, args, needles):
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    profile = (ROOT / "devices" / "grbl.toml").read_text().replace("baudrate = 115200", 'baudrate = "fast"')
    (tmp_path / "broken.toml").write_text(profile)
    (tmp_path / "other" / "taken.plt").mkdir(parents=True)
    (tmp_path / "other" / "full.plt").symlink_to("/dev/full")  # written in place, and the device is full
    args = [a.format(tmp=tmp_path) for a in args]
    if "-o" not in args:
        args += ["-o", str(out_dir / "x.gcode")]
    code, out, err = run(capsys, "export", HEXAGON, *args)
    assert_clean_error(code, out, err, out_dir, *needles)


def test_design_too_large_is_a_clear_error_without_output(tmp_path, capsys):
    job = tmp_path / "big.toml"
    shutil.copy(ROOT / "jobs" / "vase-profile.svg", tmp_path)
    job.write_text((ROOT / "jobs" / "vase-svg.toml").read_text().replace('scale = "fit"', 'scale = 1\nsheet = "A4"'))
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    for command, name in (("export", "x.plt"), ("preview", "x.svg")):
        code, out, err = run(capsys, command, job, "--device", "graphtec-ce6000", "-o", out_dir / name)
        assert_clean_error(code, out, err, out_dir, "largest scale that fits", "371.4 x 73.9 mm", "--scale fit")


def test_bad_fabrication_key_names_the_key(tmp_path, capsys):
    job = tmp_path / "job.toml"
    job.write_text(HEXAGON.read_text().replace('optimize = "greedy"', 'optimise = "greedy"'))
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    code, out, err = run(capsys, "export", job, "--device", "grbl", "-o", out_dir / "x.gcode")
    assert_clean_error(code, out, err, out_dir, "[fabrication].optimise", "unknown key")


def test_export_exit_code_in_a_real_process(tmp_path):
    result = subprocess.run([sys.executable, "-m", "foldfab", "export", str(HEXAGON), "--device", "nowhere",
                             "-o", str(tmp_path / "x.plt")], capture_output=True, text=True)
    assert result.returncode == 2 and "Traceback" not in result.stderr and "nowhere" in result.stderr
    assert list(tmp_path.iterdir()) == []


DEVICE_FILES = sorted((ROOT / "devices").glob("*.toml"))


# (the hexagon's sheet, A4 landscape, is wider than the Portrait 3 takes: refused, test_fabrication)
@pytest.mark.parametrize("device, job", [(p.stem, job) for p in DEVICE_FILES for job in JOBS
                                         if (p.stem, job.stem) != ("silhouette-portrait-3", "hexagon-fig8a")],
                         ids=lambda v: getattr(v, "stem", v))
def test_every_example_job_exports_previews_and_plots_on_every_device(tmp_path, capsys, monkeypatch, job, device):
    """Every job in jobs/ on every profile in devices/, with no option but --device (and --port)."""
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    suffix = {"gcode": ".gcode", "ebb": ".ebb", "gpgl": ".gpgl"}.get(load_device(device).protocol, ".plt")
    code, out, err = run(capsys, "export", job, "--device", device, "-o", tmp_path / f"x{suffix}")
    assert code == 0 and "foldfab: error" not in err, err
    programs = sorted(tmp_path.glob(f"x*{suffix}"))   # x.plt, or x-1.plt ... for a job split across sheets
    assert programs and all(p.stat().st_size > 0 for p in programs) and "placement    scale " in out
    code, out, err = run(capsys, "preview", job, "--device", device, "-o", tmp_path / "x.svg")
    assert code == 0, err
    previews = sorted(tmp_path.glob("x*.svg"))
    assert len(previews) == len(programs) and all("scale " in p.read_text() for p in previews)
    sheets = ["--yes"] if len(programs) > 1 else []   # answer "load sheet 2 of 3"
    code, out, err = run(capsys, "plot", job, "--device", device, "--port", "sim://?time=instant", *sheets)
    assert code == 0, err


def test_scale_fit_on_the_command_line_is_reported_and_previewed(tmp_path, capsys):
    code, out, err = run(capsys, "export", HEXAGON, "--device", "roland-gx24", "-o", tmp_path / "x.plt", "--scale", "fit")
    assert code == 0, err
    fitted = float(re.search(r"^placement    scale ([\d.]+) \(fitted to the sheet\)", out, re.M)[1])
    assert fitted > 1
    code, out, err = run(capsys, "preview", HEXAGON, "--device", "roland-gx24", "-o", tmp_path / "x.svg",
                         "--scale", "fit", "--json")
    report = json.loads(out)
    assert code == 0 and report["scale_fitted"] and report["scale"] == pytest.approx(fitted, rel=1e-3)
    assert f"scale {fitted:g} (fitted to the sheet)" in (tmp_path / "x.svg").read_text()
    code, out, err = run(capsys, "export", HEXAGON, "--device", "roland-gx24", "-o", tmp_path / "x.plt", "--json",
                         "--scale", "0.5")
    assert code == 0 and json.loads(out)["scale"] == 0.5 and not json.loads(out)["scale_fitted"]


@pytest.mark.parametrize("value", ["0", "-1", "nan", "inf", "big", "FIT"])
def test_a_bad_scale_option_is_a_usage_error(tmp_path, capsys, value):
    with pytest.raises(SystemExit) as exit_info:
        main(["export", str(HEXAGON), "--device", "grbl", "-o", str(tmp_path / "x.gcode"), "--scale", value])
    assert exit_info.value.code == 2
    assert "--scale: expected a number > 0 or fit" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_a_layer_setting_the_device_lacks_is_one_warning_line(tmp_path, capsys, monkeypatch):
    """force = 18 on a plotter without a force command: exported with one warning on stderr,
    and a warnings field in the JSON report and the JSON progress."""
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    job = tmp_path / "job.toml"
    job.write_text(HEXAGON.read_text() + "\n[fabrication.layers.valley]\nforce = 18\n")
    code, out, err = run(capsys, "export", job, "--device", "hp7475a", "-o", tmp_path / "x.hpgl")
    warning = (f"foldfab: warning: {job}: [fabrication.layers.valley].force = 18 ignored: hp7475a has no force "
               "setting (its language has no force command)")
    assert code == 0 and err.splitlines() == [warning]
    assert "FS" not in (tmp_path / "x.hpgl").read_text()
    code, out, err = run(capsys, "preview", job, "--device", "hp7475a", "-o", tmp_path / "x.svg", "--json")
    assert code == 0 and json.loads(out)["warnings"] == [warning.removeprefix("foldfab: warning: ")]
    code, out, err = run(capsys, "plot", job, "--device", "hp7475a", "--port", "sim://?time=instant", "--json")
    events = [json.loads(line) for line in out.splitlines()]
    assert code == 0 and events[0] == {"event": "warning", "message": warning.removeprefix("foldfab: warning: ")}
    assert err.splitlines() == [warning]
    code, out, err = run(capsys, "export", job, "--device", "graphtec-ce6000", "-o", tmp_path / "x.plt", "--json")
    assert code == 0 and err == "" and json.loads(out)["warnings"] == []


def test_queue_add_and_the_resume_command_keep_the_scale(tmp_path, capsys):
    """A queued job is built at the --scale given; a stopped plot's resume command repeats it,
    since the resume token belongs to the program that scale makes."""
    from foldfab.cli import build_parser
    from foldfab.cli.plot import _resume_command

    code, out, err = run(capsys, "export", HEXAGON, "--device", "grbl", "-o", tmp_path / "x.gcode", "--scale", "fit")
    assert code == 0, err
    queue = tmp_path / "q.sqlite3"
    code, out, err = run(capsys, "queue", "add", HEXAGON, "--device", "grbl", "--port", "sim://", "--queue", queue,
                         "--scale", "fit")
    assert code == 0, err
    code, out, err = run(capsys, "queue", "list", "--queue", queue, "--json")
    assert json.loads(out)[0]["program_bytes"] == (tmp_path / "x.gcode").stat().st_size
    args = build_parser().parse_args(["plot", str(HEXAGON), "--device", "grbl", "--scale", "0.75"])
    assert _resume_command(args, "sim://", "T")[-4:] == ["--scale", "0.75", "--resume", "T"]
    args = build_parser().parse_args(["plot", str(HEXAGON), "--device", "grbl"])
    assert "--scale" not in _resume_command(args, "sim://", "T")
