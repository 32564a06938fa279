"""The report and estimate from what the writer recorded equal those from the program read back,
and the read-back (``--verify``, ``plot``) refuses a program that does not draw what was planned."""

from __future__ import annotations

import json
import re
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings

from foldfab.design import load_design
from foldfab.devices import load_device
from foldfab.errors import FoldfabError
from foldfab.fabricate import fabricate
from foldfab.programs.machine import from_interpretation
from foldfab.programs.estimate import estimate, estimate_drawn
from foldfab.programs.interpret import drawn, interpret
from foldfab.programs.languages import write_program
from helpers import HEXAGON, JOBS
from helpers.cli import run
from helpers.plans import random_plans, spec, whole

RECORDING = ["hp7475a", "graphtec-ce6000", "roland-gx24", "grbl", "grbl-dragknife", "grbl-laser"]
"""Every shipped profile whose language's writer records what it draws (HP-GL, G-code)."""


def identical(one, other) -> bool:
    """Two :class:`Drawn` with equal arrays."""
    return all(np.array_equal(getattr(one, key), getattr(other, key)) for key in
               ("points", "starts", "speeds", "layers", "travels", "leads_to", "byte_ends")) and \
        (one.names, one.pauses) == (other.names, other.pauses)


def assert_same_estimate(recorded, read, device) -> None:
    ours, theirs = estimate_drawn(recorded, device), estimate_drawn(read, device)
    for key in ("total", "draw_time", "travel_time", "lift_time", "lower_bound", "link_wait"):
        assert getattr(ours, key) == pytest.approx(getattr(theirs, key), rel=1e-9, abs=1e-9), key
    assert list(ours.layers) == list(theirs.layers)
    for name, layer in ours.layers.items():
        other = theirs.layers[name]
        assert layer.pen_lifts == other.pen_lifts
        for key in ("drawn_length", "travel_length", "time"):
            assert getattr(layer, key) == pytest.approx(getattr(other, key), rel=1e-9, abs=1e-6), (name, key)
    assert recorded.pauses == read.pauses


@pytest.mark.parametrize("name", RECORDING)
@pytest.mark.parametrize("job", JOBS, ids=[j.stem for j in JOBS])
def test_every_example_job_reports_the_same_from_the_record_as_from_the_read_back(job, name):
    device = load_device(name)
    fab = fabricate(load_design(job), device, spec(**whole(job)))
    recorded = fab.program.drawn(device.frame(fab.plan.sheet))
    read = from_interpretation(interpret(fab.program, device, fab.plan.sheet))
    assert recorded is not None and len(recorded.starts) > 0
    assert identical(drawn(fab.program, device, fab.plan.sheet, verify=True), read)  # the oracle agrees
    assert_same_estimate(recorded, read, device)
    assert estimate_drawn(read, device) == estimate(interpret(fab.program, device, fab.plan.sheet), device)


@pytest.mark.parametrize("name", ["graphtec-ce6000", "grbl"])
def test_random_plans_with_pauses_and_dots_report_the_same(name):
    device = load_device(name)

    @settings(max_examples=30, deadline=None)
    @given(random_plans(device))
    def check(plan):
        program = write_program(plan, device)
        recorded = program.drawn(device.frame(plan.sheet))
        read = drawn(program, device, plan.sheet, verify=True)
        assert_same_estimate(recorded, read, device)

    check()


def corrupt(text: str, protocol: str) -> str:
    """The program with one drawn coordinate moved by 1 mm (40 HP-GL units)."""
    if protocol == "hpgl":
        match = re.search(r"PD(-?\d+),", text)
        return text[:match.start(1)] + str(int(match.group(1)) + 40) + text[match.end(1):]
    match = re.search(r"\nG1 Z-?[\d.]+ F[\d.]+\nX(-?[\d.]+)", text)   # the first stroke's second point
    return text[:match.start(1)] + f"{float(match.group(1)) + 1:g}" + text[match.end(1):]


@pytest.mark.parametrize("name", ["graphtec-ce6000", "grbl"])
def test_the_read_back_refuses_a_corrupted_program(name):
    device = load_device(name)
    fab = fabricate(load_design(HEXAGON), device)
    bad = replace(fab.program, text=corrupt(fab.program.text, device.protocol))
    drawn(fab.program, device, fab.plan.sheet, verify=True)
    assert identical(drawn(bad, device, fab.plan.sheet), fab.program.drawn(device.frame(fab.plan.sheet)))  # unread
    with pytest.raises(FoldfabError, match="read back moves stroke 1 to .* planned .*do not send it"):
        drawn(bad, device, fab.plan.sheet, verify=True)


def test_the_read_back_refuses_a_program_missing_a_stroke():
    device = load_device("graphtec-ce6000")
    fab = fabricate(load_design(HEXAGON), device)
    text = fab.program.text
    start = text.index("PU", text.index("PD"))   # the second stroke: its PU...; PD...; gone
    end = text.index("PU", text.index("PD", start))
    bad = replace(fab.program, text=text[:start] + text[end:], sections=(), pauses=())
    with pytest.raises(FoldfabError, match="draws 27 strokes .* planned 28"):
        drawn(bad, device, fab.plan.sheet, verify=True)


@pytest.mark.parametrize("name", ["graphtec-ce6000", "grbl"])
def test_export_verify_reports_what_export_reports(tmp_path, capsys, name):
    out = tmp_path / ("hexagon.plt" if name != "grbl" else "hexagon.gcode")
    rc, plain, _ = run(capsys, "export", HEXAGON, "--device", name, "-o", out, "--json")
    written = out.read_bytes()
    rc2, checked, err = run(capsys, "export", HEXAGON, "--device", name, "-o", out, "--json", "--verify")
    assert rc == rc2 == 0, err
    assert out.read_bytes() == written
    ours, theirs = json.loads(plain), json.loads(checked)
    assert ours == theirs and ours["estimated_time_s"] > 0


def test_export_verify_refuses_a_corrupted_program_and_writes_nothing(tmp_path, monkeypatch, capsys):
    """A writer that emits something else than it recorded (here: one coordinate moved)."""
    from foldfab.programs import languages

    writer = languages.WRITERS["hpgl"]

    def broken(plan, device, sink=None):   # export streams the text to its file: the file is what is checked
        program = writer(plan, device)
        text = corrupt(program.text, "hpgl")
        if sink is None:
            return replace(program, text=text)
        sink(text.encode("ascii"))
        return replace(program, text=None)

    monkeypatch.setitem(languages.WRITERS, "hpgl", broken)
    out = tmp_path / "hexagon.plt"
    assert run(capsys, "export", HEXAGON, "--device", "graphtec-ce6000", "-o", out)[0] == 0  # not checked
    out.unlink()
    rc, _, err = run(capsys, "export", HEXAGON, "--device", "graphtec-ce6000", "-o", out, "--verify")
    assert rc == 2 and "do not send it" in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []   # neither the program nor its temporary file


def test_plot_verifies_what_it_sends_and_sends_nothing_else(monkeypatch, capsys):
    from foldfab.programs import languages

    writer = languages.WRITERS["hpgl"]
    rc, out, err = run(capsys, "plot", HEXAGON, "--device", "graphtec-ce6000", "--port", "sim://?time=instant")
    assert rc == 0 and "estimate" in out, err
    monkeypatch.setitem(languages.WRITERS, "hpgl",
                        lambda plan, device, sink=None: replace(writer(plan, device), text=corrupt(writer(plan, device).text, "hpgl")))
    rc, out, err = run(capsys, "plot", HEXAGON, "--device", "graphtec-ce6000", "--port", "sim://?time=instant")
    assert rc == 2 and "do not send it" in err and "estimate" not in out


def test_a_program_without_a_record_is_read_back():
    device = load_device("silhouette-cameo-4")   # GP-GL: its writer does not record
    fab = fabricate(load_design(HEXAGON), device)
    assert fab.program.recording is None
    read = drawn(fab.program, device, fab.plan.sheet)
    assert np.array_equal(read.starts, from_interpretation(interpret(fab.program, device, fab.plan.sheet)).starts)


def test_the_read_back_refuses_a_program_drawing_at_another_speed():
    device = load_device("graphtec-ce6000")
    fab = fabricate(load_design(HEXAGON), device)
    speed = re.search(r"VS(\d+);", fab.program.text)
    bad = replace(fab.program, text=fab.program.text.replace(speed.group(0), f"VS{int(speed.group(1)) + 1};", 1))
    with pytest.raises(FoldfabError, match=r"draws stroke 1 at \d+ mm/s, planned"):
        drawn(bad, device, fab.plan.sheet, verify=True)


@pytest.mark.parametrize("count", [1, 2, 3, 1 << 16])
def test_a_sweeps_batches_hold_its_lines_in_order(count):
    from foldfab.programs.program import Sweep, sweeps

    device = load_device("graphtec-ce6000")
    fab = fabricate(load_design(HEXAGON), device)
    for sweep in [item for item in sweeps(fab.plan, device) if isinstance(item, Sweep)]:
        parts = list(sweep.batches(count=count))
        assert len(parts) == -(-len(sweep.sizes) // count)
        assert np.array_equal(np.concatenate([p for p, _ in parts]), sweep.points)
        assert np.array_equal(np.concatenate([s for _, s in parts]), sweep.sizes)
