"""foldfab export / preview: reports, files, and clear errors with nothing half-written."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from foldfab.cli import main
from foldfab.devices import load_device
from foldfab.interpret import interpret

ROOT = Path(__file__).resolve().parent.parent
HEXAGON = ROOT / "jobs" / "hexagon-fig8a.toml"


def run(capsys, *args):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


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
