"""foldfab plot on a laser: a board without laser mode is refused in one line, exit code 2; a job's
power per layer and the simulator's laser_mode option."""

from __future__ import annotations

import pytest

from helpers import HEXAGON
from helpers.cli import run, write_job


def test_plot_refuses_a_board_without_laser_mode(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    code, out, err = run(capsys, "plot", HEXAGON, "--device", "grbl-laser", "--port",
                         "sim://?time=instant&laser_mode=0", "--yes")
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "Traceback" not in err
    assert lines[0].startswith("foldfab: error: grbl-laser has $32=0") and "send $32=1" in lines[0]


@pytest.mark.parametrize("device, warned", [("grbl-laser", False), ("grbl", True)])
def test_a_jobs_power_is_a_lasers_and_ignored_with_a_warning_elsewhere(tmp_path, capsys, device, warned):
    text = HEXAGON.read_text() + "\n[fabrication.layers.valley]\npower = 0.3\n"
    job = write_job(tmp_path, text)
    code, out, err = run(capsys, "export", job, "--device", device, "-o", tmp_path / "x.gcode")
    assert code == 0, err
    assert ("power = 0.3 ignored: grbl has no power setting (it is no laser)" in err) == warned
    program = (tmp_path / "x.gcode").read_text()
    assert (" S300" in program) == (device == "grbl-laser")
