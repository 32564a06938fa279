"""GRBL laser mode: the writer's laser programs (M4 once, S on G1, G0 between strokes, M5 at
pauses and the end, no Z) and the reader's strokes with their power."""

from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import given, settings

from foldfab.devices import load_device
from foldfab.fabrication.plan import Pass, Pause, PlotPlan
from foldfab.programs.gcode import write_gcode
from foldfab.programs.interpret import interpret
from foldfab.programs.read_gcode import GcodeMachine
from helpers import JOBS
from helpers.plans import assert_round_trip, make_document, random_plans, sample_plan
from helpers.streams import fabricated

LASER_WORDS = {"G0", "G1", "G17", "G21", "G90", "M0", "M2", "M4", "M5"}


def check_laser_rules(text: str) -> None:
    """No Z, no dwell; M4 once per run between pauses, M5 before every M0 and before M2; S words
    and G1 moves only with the beam on (the round trip checks the G0 between strokes)."""
    lines = [re.sub(r"\([^()]*\)", "", line).strip() for line in text.split("\n")[:-1]]
    lines = [line for line in lines if line]
    assert lines[-1] == "M2" and "\r" not in text
    words = [set(re.findall(r"[GM]\d+", line)) for line in lines]
    assert set().union(*words) <= LASER_WORDS
    assert not any("Z" in line or "P" in line for line in lines)
    beam, motion = False, None
    for line, codes in zip(lines, words):
        motion = next((c for c in codes if c in ("G0", "G1")), motion)
        if "M4" in codes:
            assert not beam, "M4 while the beam is already on"
            assert line == "M4 S0"
            beam = True
        elif "M5" in codes:
            beam = False
        elif codes & {"M0", "M2"}:
            assert not beam, f"{line} with the beam on"
        elif "S" in line:
            assert motion == "G1" and beam and "X" in line, line
        if "X" in line and motion == "G1":
            assert beam
    assert not beam


@pytest.fixture(scope="module")
def laser():
    return load_device("grbl-laser")


def test_laser_program_lines(laser):
    doc = make_document({1: [[10 + 10j, 20 + 10j], [30 + 10j, 40 + 10j]], 3: [[10 + 20j, 20 + 20j, 20 + 30j]]})
    plan = PlotPlan(doc, [Pass(1, "valley", laser.tool_for("valley")),
                          Pause("Check the focus."),
                          Pass(3, "cut", laser.tool_for("cut"))], laser.sheet)
    program = write_gcode(plan, laser)
    lines = program.text.splitlines()
    assert lines == [
        "(foldfab program for grbl-laser, sheet 210 x 297 mm)",
        "G21 G90 G17",
        "M5",
        "(valley pass, tool 1, sweep 1 of 1)",
        "G0 X10 Y287",
        "M4 S0",
        "G1 X20 Y287 F2400 S150",
        "G0 X30 Y287",
        "G1 X40 Y287",
        "M5",
        "G0 X0 Y0",
        "(Check the focus.)",
        "M0",
        "(cut pass, tool 1, sweep 1 of 1)",
        "X10 Y277",
        "M4 S0",
        "G1 X20 Y277 F600 S600",
        "X20 Y267",
        "M5",
        "G0 X0 Y0",
        "M2",
    ]
    check_laser_rules(program.text)
    assert_round_trip(plan, laser, program)


def test_laser_round_trip_sample(laser):
    plan = sample_plan(laser, mountain_passes=3)
    program = write_gcode(plan, laser)
    check_laser_rules(program.text)
    assert_round_trip(plan, laser, program)


def test_laser_round_trip_random(laser):
    @settings(max_examples=40, deadline=None)
    @given(random_plans(laser))
    def check(plan):
        program = write_gcode(plan, laser)
        check_laser_rules(program.text)
        assert_round_trip(plan, laser, program)

    check()


def test_a_job_power_per_layer_comes_back_per_stroke(laser):
    doc = make_document({1: [[10 + 10j, 20 + 10j]], 2: [[10 + 20j, 20 + 20j]], 3: [[10 + 30j, 20 + 30j]]})
    plan = PlotPlan(doc, [Pass(1, "valley", laser.tool_for("valley", {"power": 0.25})),
                          Pass(2, "mountain", laser.tool_for("mountain", {"power": 0.0625})),
                          Pass(3, "cut", laser.tool_for("cut", {"power": 1}))], laser.sheet)
    program = write_gcode(plan, laser)
    assert [line.split(" S")[1] for line in program.text.splitlines() if " S" in line and "G1" in line] == \
        ["250", "62.5", "1000"]
    assert_round_trip(plan, laser, program)


def read(text: str, device) -> list[tuple[float, list]]:
    """(power, points as device mm) of each stroke ``text`` draws."""
    machine = GcodeMachine(device, device.frame(device.sheet), None)
    result = machine.run(text)
    frame = device.frame(device.sheet)
    return [(s.power, frame.to_device(s.points).round(3).tolist()) for s in result.strokes]


def test_the_reader_follows_grbl_laser_mode(laser):
    # G0 never burns, S0 does not, M3 is constant power, a change of S starts a new stroke,
    # S above $30 is full power, M5 and M2 switch the beam off.
    text = "\n".join([
        "G21 G90", "M4 S500", "G0 X10 Y0", "G1 X20 F600", "X30 S250", "G0 X40", "G1 X50 S0",
        "X60 S1500", "M5", "X70", "M3 S100", "X80", "M2", "G1 X90", ""])
    assert read(text, laser) == [
        (0.5, [[10, 0], [20, 0]]), (0.25, [[20, 0], [30, 0]]), (1.0, [[50, 0], [60, 0]]),
        (0.1, [[70, 0], [80, 0]])]


def test_non_laser_strokes_have_no_power():
    grbl = load_device("grbl")
    program = write_gcode(sample_plan(grbl), grbl)
    machine = GcodeMachine(grbl, grbl.frame(grbl.sheet), program)
    assert {s.power for s in machine.run(program.text).strokes} == {None}


def pygcode_burns(text: str) -> list[tuple[float, list[tuple[float, float]]]]:
    """(S, device points) of each burn as pygcode's machine (an independent G-code reader, after
    LinuxCNC) reads the program: moves in G1 with M3 or M4 on and S above 0, one burn while they
    follow each other at one S.  pygcode raises on a word or G/M code it does not know."""
    from pygcode import Line, Machine
    from pygcode.gcodes import MODAL_GROUP_MAP

    machine, burns, burning = Machine(), [], False
    for raw in text.splitlines():
        block = Line(raw).block
        start = (machine.pos.X, machine.pos.Y)
        machine.process_block(block)
        if not block.gcodes and not block.modal_params:
            continue  # a comment
        groups = machine.mode.modal_groups
        speed = float(str(groups[MODAL_GROUP_MAP["spindle_speed"]])[1:])
        end = (machine.pos.X, machine.pos.Y)
        on = (end != start and str(groups[MODAL_GROUP_MAP["motion"]]) == "G01"
              and str(groups[MODAL_GROUP_MAP["spindle"]]) in ("M03", "M04") and speed > 0)
        if on and burning and burns[-1][0] == speed:
            burns[-1][1].append(end)
        elif on:
            burns.append((speed, [start, end]))
        burning = on
    return burns


@pytest.mark.parametrize("strategy", ["force", "perforate", "two-sided"])
@pytest.mark.parametrize("job", JOBS, ids=[j.stem for j in JOBS])
def test_every_example_job_round_trips_and_pygcode_reads_the_same_burns(job, strategy, laser):
    """Every crease and the outline come back from the program with their layer's power, and
    pygcode, reading the same text, burns the same lines at the same power."""
    fab = fabricated(str(job), "grbl-laser", strategy)
    check_laser_rules(fab.program.text)
    assert_round_trip(fab.plan, laser, fab.program)
    ours = interpret(fab.program, laser, fab.plan.sheet).strokes
    frame = laser.frame(fab.plan.sheet)
    theirs = pygcode_burns(fab.program.text)
    assert len(theirs) == len(ours) > 0
    for (speed, points), stroke in zip(theirs, ours):
        assert speed == pytest.approx(stroke.power * laser.gcode.spindle_max, abs=1e-9)
        assert np.allclose(points, frame.to_device(stroke.points), atol=1e-9, rtol=0)
    if strategy == "perforate":  # the dashes cut: every stroke at the cut's power
        assert {round(s.power, 6) for s in ours} == {laser.layers["cut"].power}
