"""The command line says when it moves a drag knife's path, in the report and the preview."""

from __future__ import annotations

import json

from helpers import HEXAGON
from helpers.cli import run


def test_export_and_preview_name_the_blade_compensation(tmp_path, capsys):
    rc, out, err = run(capsys, "export", HEXAGON, "--device", "grbl-dragknife", "-o", tmp_path / "out.gcode")
    line = "cut: drag knife compensated for a 0.25 mm blade offset, swivels at corners over 5 degrees, 0.5 mm overcut"
    assert rc == 0 and f"blade        {line}" in out.splitlines()
    rc, out, err = run(capsys, "export", HEXAGON, "--device", "grbl-dragknife", "-o", tmp_path / "o.gcode", "--json")
    assert rc == 0 and json.loads(out)["blades"] == [line]
    rc, out, err = run(capsys, "preview", HEXAGON, "--device", "grbl-dragknife", "-o", tmp_path / "p.svg")
    assert rc == 0 and line in (tmp_path / "p.svg").read_text()
    rc, out, err = run(capsys, "export", HEXAGON, "--device", "grbl", "-o", tmp_path / "plain.gcode", "--json")
    assert rc == 0 and json.loads(out)["blades"] == []
