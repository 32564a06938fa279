"""GRBL 1.1 G-code writer: round trips (Z and servo pens), the GRBL line rules, pauses."""

from __future__ import annotations

import copy
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from foldfab.devices import load_device
from foldfab.errors import FoldfabError
from foldfab.programs.gcode import write_gcode
from foldfab.devices import Tool
from foldfab.fabrication.plan import Pass, Pause, PlotPlan
from foldfab.programs.program import fmt_number
from helpers import ROOT
from helpers.plans import assert_round_trip, make_document, random_plans, sample_plan, servo_device

ALLOWED = {"G0", "G1", "G4", "G17", "G20", "G21", "G90", "G91", "G92", "M0", "M2", "M3", "M5"}
WORD = re.compile(r"([A-Z])(-?\d+(?:\.\d{1,3})?)")


def check_grbl_rules(text: str) -> None:
    """\\n endings, < 80 characters, only GRBL 1.1 words, <= 3 decimals, no repeated modal F."""
    assert "\r" not in text and text.endswith("M2\n")
    feed = None
    for line in text.split("\n")[:-1]:
        assert len(line) < 80 and line.isascii()
        code = re.sub(r"\([^()]*\)", "", line)
        assert "(" not in code and ")" not in code and ";" not in code
        words = code.split()
        for word in words:
            match = WORD.fullmatch(word)
            assert match, f"bad word {word!r} in {line!r}"
            letter, number = match.groups()
            assert letter in "GMXYZFSP"
            if letter in "GM":
                assert f"{letter}{number}" in ALLOWED
            if letter == "F":
                assert number != feed, f"repeated feed in {line!r}"
                feed = number


@pytest.mark.parametrize("pen", ["z", "servo"])
def test_round_trip_sample(pen, tmp_path):
    device = load_device("grbl") if pen == "z" else servo_device(tmp_path)
    plan = sample_plan(device, mountain_passes=3)
    program = write_gcode(plan, device)
    check_grbl_rules(program.text)
    assert_round_trip(plan, device, program)


@pytest.mark.parametrize("pen", ["z", "servo"])
def test_round_trip_random(pen, tmp_path):
    device = load_device("grbl") if pen == "z" else servo_device(tmp_path)

    @settings(max_examples=40, deadline=None)
    @given(random_plans(device))
    def check(plan):
        program = write_gcode(plan, device)
        check_grbl_rules(program.text)
        assert_round_trip(plan, device, program)

    check()


def test_deterministic():
    device = load_device("grbl")
    plan = sample_plan(device)
    assert write_gcode(plan, device) == write_gcode(copy.deepcopy(plan), device)


def test_header_pen_moves_and_end():
    device = load_device("grbl")
    doc = make_document({1: [[10 + 10j, 20 + 10j, 20 + 20j]]})
    plan = PlotPlan(doc, [Pass(1, "cut", device.tool_for("cut"))], device.sheet)
    lines = write_gcode(plan, device).text.splitlines()
    assert lines == [
        "(foldfab program for grbl, sheet 210 x 297 mm)",
        "G21 G90 G17",
        "G0 Z3",
        "(cut pass, tool 1, sweep 1 of 1)",
        "X10 Y287",
        "G1 Z-1 F600",
        "X20 Y287 F900",
        "X20 Y277",
        "G0 Z3",
        "X0 Y0",
        "M2",
    ]


def test_servo_pen_dwells(tmp_path):
    device = servo_device(tmp_path)
    doc = make_document({1: [[10 + 10j, 20 + 10j]]})
    plan = PlotPlan(doc, [Pass(1, "valley", device.tool_for("valley"))], device.sheet)
    lines = write_gcode(plan, device).text.splitlines()
    assert lines[2:4] == ["M3 S50", "G4 P0.2"]
    assert lines[5:10] == ["G0 X10 Y287", "M3 S30", "G4 P0.2", "G1 X20 Y287 F1800", "M3 S50"]


def test_pause_is_m0_after_parking_with_the_message_as_comments():
    device = load_device("grbl")
    plan = sample_plan(device)
    message = "Flip the sheet (about its left edge) so that the mountain side faces up; " \
              "then press cycle start — and mind the clamps."
    plan.steps[1] = Pause(message)
    program = write_gcode(plan, device)
    check_grbl_rules(program.text)
    (pause,) = program.pauses
    before = program.text[:pause.offset].splitlines()
    assert before[-1] == "M0" and before[-4] == "X0 Y0" and before[-5] == "G0 Z3"
    comment = " ".join(line[1:-1] for line in before[-3:-1])
    assert comment == message.replace("(", "[").replace(")", "]").replace("—", "?")
    assert pause.message == message


def test_tool_change_pauses():
    device = load_device("grbl")
    doc = make_document({1: [[10 + 10j, 20 + 10j]], 2: [[10 + 20j, 20 + 20j]]})
    plan = PlotPlan(doc, [Pass(1, "valley", device.tool_for("valley")),
                          Pass(2, "cut", device.tool_for("cut", {"pen": 2}))], device.sheet)
    program = write_gcode(plan, device)
    assert [p.message for p in program.pauses] == ["Load tool 2 for the cut pass, then resume."]
    assert program.text[:program.pauses[0].offset].endswith(
        "(Load tool 2 for the cut pass, then resume.)\nM0\n")


def test_layer_without_depth_and_force_are_refused():
    device = load_device("grbl")
    doc = make_document({1: [[10 + 10j, 20 + 10j]]})
    plan = PlotPlan(doc, [Pass(1, "perforation", Tool(1, None, 20.0))], device.sheet)
    with pytest.raises(FoldfabError, match=r"no \[layers.perforation\] table"):
        write_gcode(plan, device)
    plan = PlotPlan(doc, [Pass(1, "cut", Tool(1, 100.0, 20.0))], device.sheet)
    with pytest.raises(FoldfabError, match="tool.force.*set the depth with pen_down"):
        write_gcode(plan, device)


def test_out_of_area_guard():
    device = load_device("grbl")  # 300 x 300 mm machine, A3 sheet 297 x 420
    doc = make_document({1: [[10 + 10j, 280 + 410j]]})
    plan = PlotPlan(doc, [Pass(1, "cut", device.tool_for("cut"))], (297.0, 420.0))
    with pytest.raises(FoldfabError) as error:
        write_gcode(plan, device)
    assert "design is 270.0 x 400.0 mm" in str(error.value)
    assert "plottable area 300 x 300 mm" in str(error.value)
    assert "largest scale that fits: 0.750" in str(error.value)



@settings(max_examples=300)
@given(value=st.one_of(st.floats(-1e5, 1e5, allow_nan=False), st.integers(-10**5, 10**5).map(lambda n: n / 1000)),
       decimals=st.integers(0, 4))
def test_numbers_are_written_shortest(value, decimals):
    """The value at ``decimals`` places, trailing zeros and a bare point dropped, no "-0"."""
    text = fmt_number(value, decimals)
    assert float(text) == float(f"{value:.{decimals}f}")
    assert text != "-0" and not text.endswith(".")
    assert "." not in text or (not text.endswith("0") and len(text.split(".")[1]) <= decimals)


def pygcode_cuts(text: str, pen_up: float) -> list[list[tuple[float, float]]]:
    """The XY paths the tool cuts as pygcode's machine (an independent G-code reader, after
    LinuxCNC; it raises on a word or G/M code it does not know) reads the program: runs of G1
    moves in the plane while Z is below the pen-up height."""
    from pygcode import Line, Machine

    machine, cuts, cutting = Machine(), [], False
    for raw in text.splitlines():
        start = (machine.pos.X, machine.pos.Y)
        machine.process_block(Line(raw).block)
        end = (machine.pos.X, machine.pos.Y)
        on = end != start and machine.pos.Z < pen_up
        if on and cutting:
            cuts[-1].append(end)
        elif on:
            cuts.append([start, end])
        cutting = on if end != start else cutting and machine.pos.Z < pen_up
    return cuts


@pytest.mark.parametrize("name", ["grbl", "grbl-dragknife"])
@pytest.mark.parametrize("job", sorted((ROOT / "jobs").glob("*.toml")), ids=lambda p: p.stem)
def test_pygcode_reads_every_example_program_and_cuts_what_we_read(name, job):
    """The hidden-reader principle for G-code tools: pygcode accepts every program, and the
    strokes it cuts are the ones foldfab's reader finds (a drag knife's swivels included)."""
    from foldfab.programs.interpret import interpret
    from helpers.streams import fabricated

    device = load_device(name)
    fab = fabricated(str(job), name, "force")
    ours = interpret(fab.program, device, fab.plan.sheet).strokes
    theirs = pygcode_cuts(fab.program.text, device.gcode.pen_up)
    frame = device.frame(fab.plan.sheet)
    assert len(theirs) == len(ours) > 0
    for points, stroke in zip(theirs, ours):
        assert np.allclose(points, frame.to_device(stroke.points), atol=1e-9, rtol=0)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.floats(-1e5, 1e5, allow_nan=False), st.floats(-1e5, 1e5, allow_nan=False)) |
                st.tuples(st.floats(-0.002, 0.002), st.sampled_from([0.0, -0.0, 0.0005, -0.0005, 10.0, 1e5])),
                min_size=1, max_size=40))
def test_coordinates_formatted_at_once_are_each_formatted_alone(points):
    """The writer's bulk formatting of X/Y words is :func:`fmt_number`'s, number by number."""
    from foldfab.programs.gcode import _xy_words

    words = _xy_words(np.asarray(points, dtype=float))
    assert words == [f"X{fmt_number(x, 3)} Y{fmt_number(y, 3)}" for x, y in points]


@settings(max_examples=300, deadline=None)
@given(st.lists(st.floats(-1e5, 1e5, allow_nan=False) |
                st.integers(-10**8, 10**8).map(lambda n: n / 2000) |  # ties and values next to them
                st.integers(-10**8, 10**8).map(lambda n: np.nextafter(n / 2000, np.inf)),
                min_size=1, max_size=40))
def test_the_record_rounds_as_the_text_is_written(values):
    """What the writer records is what its words say, near ties too (0.0005 is written 0.001)."""
    from foldfab.programs.gcode import round_as_text

    rounded = round_as_text(np.asarray(values, dtype=float), 3)
    assert rounded.tolist() == [float("%.3f" % v) for v in values]


def test_a_program_through_rounding_ties_reads_back_as_recorded():
    """Points a half-thousandth apart (ties of the three decimals) reach the report as the text
    gives them: ``--verify`` and every plot's check accept the program."""
    from foldfab.programs.interpret import drawn

    device = load_device("grbl")
    steps = np.arange(200) * 0.0005
    line = (10 + steps) + 1j * (20 + steps[::-1])
    plan = PlotPlan(make_document({1: [line]}), [Pass(1, "valley", device.tool_for("valley", {}))], (210.0, 297.0))
    program = write_gcode(plan, device)
    read = drawn(program, device, plan.sheet, verify=True)
    assert np.array_equal(read.points, program.drawn(device.frame(plan.sheet)).points)
