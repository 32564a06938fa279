"""Drag-knife compensation in profiles, jobs, plans, programs and previews."""

from __future__ import annotations

import shutil
import subprocess
import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from foldfab.design import load_design
from foldfab.devices import Blade, load_device
from foldfab.errors import FoldfabError
from foldfab.fabricate import fabricate
from foldfab.fabrication.plan import Pass
from foldfab.fabrication.spec import job_spec, parse_fabrication
from foldfab.programs.interpret import interpret
from foldfab.programs.preview import render_preview
from helpers import HEXAGON
from helpers.blade import as_complex, distance_to_polyline, dragged_tip

SVG = "{http://www.w3.org/2000/svg}"


def profile_text(name: str) -> str:
    return Path(load_device(name).source).read_text()


def cutter_without_firmware_offset(folder: Path) -> Path:
    """The Roland cutter as if its firmware did not compensate: foldfab sets a 0.25 mm blade."""
    text = profile_text("roland-gx24").replace("firmware_blade_offset = true", "firmware_blade_offset = false")
    text = text.replace("[layers.cut]\n", "[layers.cut]\nblade_offset = 0.25\novercut = 0.5\n")
    path = folder / "roland-drag.toml"
    path.write_text(text)
    return path


def fabricated(device, **cut):
    design = load_design(HEXAGON)
    spec = job_spec(design.job)
    if cut:
        spec = replace(spec, layers={**spec.layers, "cut": {**spec.layers.get("cut", {}), **cut}})
    return fabricate(design, device, spec)


def cut_pass(plan) -> Pass:
    return next(step for step in plan.steps if isinstance(step, Pass) and step.name == "cut")


def test_profiles_say_who_compensates():
    knife = load_device("grbl-dragknife")
    assert knife.blades == {"cut": Blade(offset=0.25, swivel_angle=5.0, overcut=0.5)}
    assert not knife.firmware_blade_offset
    # the HP-GL cutters' own setting, and GP-GL's FC (the profile's [gpgl] blade_offset)
    for name in ("graphtec-ce6000", "roland-gx24", "silhouette-cameo-4", "silhouette-portrait-3",
                 "graphtec-ce6000-gpgl"):
        assert load_device(name).firmware_blade_offset and not load_device(name).blades
    assert not load_device("grbl").blades and not load_device("grbl").firmware_blade_offset


@pytest.mark.parametrize("edit, words", [
    (lambda t: t.replace("[layers.valley]\n", "[layers.valley]\nblade_offset = 0.25\n"),
     ["layers.valley.blade_offset", "scores"]),
    (lambda t: t.replace("blade_offset = 0.25 ", "blade_offset = 7 "), ["layers.cut.blade_offset", "0 to 5"]),
    (lambda t: t.replace("swivel_angle = 5 ", "swivel_angle = 180 "), ["layers.cut.swivel_angle", "0 to 179"]),
    (lambda t: t.replace("overcut = 0.5 ", "overcut = -1 "), ["layers.cut.overcut", "0 to 50"]),
    (lambda t: t.replace('port = "/dev/ttyUSB0"', 'port = "/dev/ttyUSB0"\nfirmware_blade_offset = true'),
     ["layers.cut.blade_offset", "firmware_blade_offset = true"]),
    (lambda t: t.replace('port = "/dev/ttyUSB0"', 'port = "/dev/ttyUSB0"\nfirmware_blade_offset = 1'),
     ["firmware_blade_offset", "true or false"]),
])
def test_profile_blade_mistakes_name_the_key(tmp_path, edit, words):
    path = tmp_path / "knife.toml"
    path.write_text(edit(profile_text("grbl-dragknife")))
    with pytest.raises(FoldfabError) as error:
        load_device(str(path))
    assert str(path) in str(error.value) and all(w in str(error.value) for w in words), str(error.value)


def test_job_layers_override_the_blade_and_scored_layers_refuse_it():
    knife = load_device("grbl-dragknife")
    plan = fabricated(knife, blade_offset=0.4, overcut=0).plan
    assert cut_pass(plan).blade == Blade(offset=0.4, swivel_angle=5.0, overcut=0.0)
    assert all(step.blade is None for step in plan.steps if isinstance(step, Pass) and step.name != "cut")
    design = load_design(HEXAGON)
    spec = parse_fabrication({"layers": {"valley": {"blade_offset": 0.25}}}, "job.toml")
    scored = r"hexagon-fig8a.toml: \[fabrication.layers.valley\]: blade_offset = 0.25 on a scored layer"
    with pytest.raises(FoldfabError, match=scored):
        fabricate(design, knife, spec)
    # perforated creases are cut: their dashes take the cut's blade, and may set their own
    spec = parse_fabrication({"strategy": "perforate", "layers": {"valley": {"blade_offset": 0.3}}}, "job.toml")
    blades = {step.name: step.blade for step in fabricate(design, knife, spec).plan.steps if isinstance(step, Pass)}
    assert blades["valley"].offset == 0.3 and blades["mountain"] == knife.blades["cut"]
    with pytest.raises(FoldfabError, match="layers.cut.blade_offset"):
        fabricated(knife, blade_offset="thin")


@pytest.mark.parametrize("name", ["roland-gx24", "silhouette-cameo-4"])
def test_a_cutter_that_compensates_itself_ignores_the_job_blade_with_a_warning(name):
    fab = fabricated(load_device(name), blade_offset=0.3)
    assert cut_pass(fab.plan).blade is None
    assert any("blade_offset = 0.3 ignored" in w and "firmware_blade_offset" in w for w in fab.warnings)
    plain = fabricated(load_device(name))
    assert fab.program.text == plain.program.text


@pytest.mark.parametrize("protocol", ["gcode", "hpgl"])
def test_the_tip_of_the_emitted_program_follows_every_outline_corner(tmp_path, protocol):
    device = load_device("grbl-dragknife" if protocol == "gcode" else str(cutter_without_firmware_offset(tmp_path)))
    blade = device.blades["cut"]
    fab = fabricated(device)
    outline = [as_complex(np.asarray(line)) for line in fab.layout.document.layers[3]]
    result = interpret(fab.program, device, fab.plan.sheet)
    cuts = [as_complex(s.points) for s in result.strokes if s.layer == "cut"]
    assert len(cuts) == len(outline) == 1
    # the tip runs the outline (from wherever the optimizer started the loop), then the overcut
    (axis,) = cuts
    tip = dragged_tip(axis, blade.offset)
    assert distance_to_polyline(tip, outline[0]).max() <= device.resolution
    assert distance_to_polyline(outline[0], tip).max() <= device.resolution  # it passes every corner
    # ... past its start by the overcut (the loop's first side is longer than that)
    assert abs(tip[-1] - tip[0]) == pytest.approx(blade.overcut, abs=device.resolution)
    # scoring is never compensated: the creases are those of the same job without a blade
    plain = fabricated(device, blade_offset=0, overcut=0)
    unblade = interpret(plain.program, device, plain.plan.sheet)
    for layer in ("valley", "mountain"):
        ours = [s.points for s in result.strokes if s.layer == layer]
        theirs = [s.points for s in unblade.strokes if s.layer == layer]
        assert len(ours) == len(theirs) and all(np.array_equal(a, b) for a, b in zip(ours, theirs))
    assert not np.array_equal(cuts[0], [s.points for s in unblade.strokes if s.layer == "cut"][0])
    if protocol == "hpgl":   # an independent reader takes the swivels (.ci/run installs hp2xx)
        assert shutil.which("hp2xx"), "hp2xx is missing: apt-get install hp2xx"
        (tmp_path / "cut.hpgl").write_text(fab.program.text)
        done = subprocess.run(["hp2xx", "-q", "-m", "svg", "-f", str(tmp_path / "cut.svg"), str(tmp_path / "cut.hpgl")],
                              capture_output=True, text=True, timeout=60)
        assert (done.returncode, done.stdout, done.stderr) == (0, "", "")


def test_the_preview_shows_the_swivel_arcs_at_the_outline_corners():
    device = load_device("grbl-dragknife")
    blade = device.blades["cut"]
    fab = fabricated(device)
    svg = render_preview(interpret(fab.program, device, fab.plan.sheet), device, fab.plan)
    cut = next(g for g in ET.fromstring(svg).iter(f"{SVG}g") if g.get("data-layer") == "cut")
    drawn = np.array([[float(v) for v in p.split(",")] for e in cut for p in e.get("points").split()])
    drawn = as_complex(drawn)
    loop = as_complex(np.asarray(fab.layout.document.layers[3].lines[0]))[:-1]
    turns = np.degrees(np.abs(np.angle((np.roll(loop, -1) - loop) / (loop - np.roll(loop, 1)))))
    corners = loop[turns > blade.swivel_angle]
    assert len(corners) >= 4
    for corner in corners:
        # the knife swings round the corner at the blade offset: an arc of several points
        on_arc = np.abs(np.abs(drawn - corner) - blade.offset) <= 2e-3
        assert on_arc.sum() >= 3, corner
        spread = np.degrees(np.ptp(np.unwrap(np.angle(drawn[on_arc] - corner))))
        assert spread >= 0.9 * min(turns[np.abs(loop - corner).argmin()], 360 - spread)


def test_a_design_fitted_to_the_sheet_leaves_room_for_the_knife_to_swing():
    knife = load_device("grbl-dragknife")
    design = load_design(HEXAGON)
    spec = replace(job_spec(design.job), margin=0.0, scale="fit")
    fab = fabricate(design, knife, spec)   # the writer refuses any point outside the sheet or reach
    axis = np.concatenate([as_complex(np.asarray(line)) for line in fab.plan.document.layers[3]])
    width, height = fab.plan.sheet
    edge = min(axis.real.min(), axis.imag.min(), width - axis.real.max(), height - axis.imag.max())
    assert 0 <= edge <= 0.01   # fitted up to the sheet's edge, the knife's swing included
