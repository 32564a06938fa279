"""Interpreters (HPGL tokenizer, HPGL and G-code machines) and the time estimate.

Also home of the helpers the writer tests share: plan builders and the round-trip check.
"""

from __future__ import annotations

import dataclasses
import math
from itertools import accumulate
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from foldfab.devices import DeviceProfile, load_device
from foldfab.programs.estimate import (axis_factors, estimate, junction_limits, move_times, plan_speeds,
                              planned_segments, segment_times, straight_runs)
from foldfab.programs.interpret import interpret
from foldfab.programs.machine import Interpretation, Stroke, Travel
from foldfab.programs.read_gcode import GcodeMachine
from foldfab.programs.read_hpgl import HPGLMachine, HPGLTokenizer
from foldfab.fabrication.plan import Pass, PlotPlan
from foldfab.programs.languages import write_program
from helpers import DEVICES
from helpers.plans import expected_strokes, make_document, random_plans, sample_plan, servo_device



# --- HPGL tokenizer -------------------------------------------------------------------


def tokens(data: bytes):
    tok = HPGLTokenizer()
    return [(c.name, c.params, c.offset, c.text, c.error) for c in tok.feed(data) + tok.close()]


def test_tokenizer_separators_terminators_and_offsets():
    data = b"IN;SP1;PU 10 , -20;PD+3-4,5.5 6\nPA;PU;LBhello;world\x03VS10PD1,2"
    assert tokens(data) == [
        ("IN", (), 0, None, None),
        ("SP", (1.0,), 3, None, None),
        ("PU", (10.0, -20.0), 7, None, None),
        ("PD", (3.0, -4.0, 5.5, 6.0), 19, None, None),
        ("PA", (), 32, None, None),
        ("PU", (), 35, None, None),
        ("LB", (), 38, "hello;world", None),
        ("VS", (10.0,), 52, None, None),
        ("PD", (1.0, 2.0), 56, None, None),
    ]


def test_tokenizer_device_control_and_errors():
    data = b"\x1b.B\x1b.@;17:PU1,2;XX1..2;P;"
    result = tokens(data)
    assert result[0][:3] == ("ESC.B", (), 0)
    assert result[1][:3] == ("ESC.@", (17.0,), 3)
    assert result[2][:2] == ("PU", (1.0, 2.0))
    assert result[3][0] == "XX" and result[3][4] is not None
    assert result[4][0] == "P" and result[4][4] == "not a mnemonic"


HPGL_PIECES = [
    b"IN", b"SP", b"PU", b"PD", b"pa", b"Pr", b"VS", b"XY", b"P", b"LB", b"lb", b"\xe9a",
    b"\x1b.B", b"\x1b.@", b"\x1b.K", b"\x1bX", b";", b":", b"\x03", b",", b" ", b"\n", b"\t",
    b"+", b"-", b".", b"1", b"23", b"4.5", b"-60", b"7,8", b",9", b"hello", b"PD1,2,3,4;",
    b"\x1b.@1;2:",
]


@settings(max_examples=300, deadline=None)
@given(st.lists(st.sampled_from(HPGL_PIECES), max_size=40).map(b"".join),
       st.lists(st.integers(1, 9), min_size=1, max_size=40), st.booleans())
@example(b"IN1,IN", [1], False)  # Python 3.11.2's possessive repeats read "1," as integers (gh-106052)
def test_tokenizer_is_incremental(data, cuts, split):
    """Any split of the byte stream gives the same commands as feeding it whole.

    Fed whole, complete commands take the fast path; fed in small pieces, most go byte by
    byte through the state machine; labels, ESC sequences, errors, lone letters and
    coordinate pairs (``split_coordinates``) must come out the same either way.
    """

    def read(pieces):
        tok, got = HPGLTokenizer(split_coordinates=split), []
        for piece in pieces:
            got += tok.feed(piece)
            assert tok.committed <= tok.offset
        assert tok.offset == len(data)
        committed = tok.committed
        got += tok.close()
        return [(c.name, c.params, c.offset, c.text, c.error, c.part) for c in got], committed

    ends = [*accumulate(cuts), len(data)]
    pieces = [data[a:b] for a, b in zip([0, *ends], ends)]
    assert read(pieces) == read([data])


@pytest.mark.parametrize("split", [False, True])
def test_tokenizer_fast_and_byte_by_byte_readings_agree(split):
    data = b"IN;SP1;PD1,2,-3,4;PU 1 2 3-4;pa.5,1.;VS1..2;XY;P;LBa;b\x03\x1b.@1;2:PR1,2\x1b.K;" \
        b"PD1,2,3,4;SP2;\x1b.@3:PD1,2"

    def read(pieces):
        tok = HPGLTokenizer(split_coordinates=split)
        got = [c for piece in pieces for c in tok.feed(piece)] + tok.close()
        return [(c.name, c.params, c.offset, c.text, c.error, c.part) for c in got]

    whole = read([data])
    assert read(data[i:i + 1] for i in range(len(data))) == whole
    if not split:
        assert [c[:3] for c in whole[:5]] == [
            ("IN", (), 0), ("SP", (1.0,), 3), ("PD", (1.0, 2.0, -3.0, 4.0), 7),
            ("PU", (1.0, 2.0, 3.0, -4.0), 18), ("PA", (0.5, 1.0), 29)]
        assert whole[5][0] == "VS" and whole[5][4] is not None


# --- HPGL machine ---------------------------------------------------------------------


def test_hpgl_machine_relative_pen_states_and_per_pen_settings():
    device = load_device("hp7475a")  # origin bottom-left + (10, 4) mm, y up, 40 units/mm
    text = "IN;SP1;VS2;VS3,2;PA400,400;PD;PR400,0,0,400;PU;PA0,0;SP2;PD400,400;PU;SP3;PD;PU;"
    result = interpret(text, device)
    first, second, dot = result.strokes
    sheet_h = device.sheet[1]
    assert first.points.tolist() == [[20, sheet_h - 14], [30, sheet_h - 14], [30, sheet_h - 24]]
    assert (first.pen, first.speed) == (1, 20.0)
    assert (second.pen, second.speed) == (2, 30.0)  # "VS3,2" is pen 2's speed
    assert second.points.tolist() == [[10, sheet_h - 4], [20, sheet_h - 14]]
    assert len(dot.points) == 1 and dot.speed == 20.0
    assert result.strokes[0].section is None and result.strokes[0].layer == "pen 1"
    assert [t.end for t in result.travels] == [(20.0, sheet_h - 14), (10.0, sheet_h - 4)]


def test_hpgl_machine_reports_what_it_does_not_understand():
    result = interpret("IN;SP1;CI50;PD1,2,3;", load_device("hp7475a"))
    assert result.ignored[0] == "CI"
    assert "odd coordinate count" in result.ignored[1]


# --- G-code machine -------------------------------------------------------------------


def test_gcode_machine_units_relative_moves_offsets_and_comments():
    device = load_device("grbl")  # origin bottom-left, y up; pen down at Z <= -0.3
    text = "\n".join([
        "G21 G90", "G0 Z3", "G0 X10 Y20", "G1 Z-0.3 F600", "G91", "G1 X5 F1200", "Y5",
        "G90 G0 Z3", "G20", "G0 X1 Y1", "G21", "G92 X0 Y0", "G1 Z-1 F60", "G1 X10 F300",
        "G0 Z3", "(Turn the sheet)", "(over)", "M0", "M2", "",
    ])
    result = interpret(text, device)
    h = device.sheet[1]
    first, second = result.strokes
    assert first.points.tolist() == [[10, h - 20], [15, h - 20], [15, h - 25]]
    assert (first.speed, first.pen_down) == (20.0, -0.3)
    assert second.points.tolist() == [[25.4, h - 25.4], [35.4, h - 25.4]]  # G92 offset
    assert (second.speed, second.pen_down) == (5.0, -1.0)
    assert result.pauses[0].message == "Turn the sheet over"
    assert result.pauses[0].offset == text.index("M0") + 3
    assert result.ignored == []


def test_gcode_machine_servo_pen(tmp_path):
    device = servo_device(tmp_path)
    program = "M3 S50\nG0 X1 Y1\nM3 S20\nG4 P0.2\nG1 X2 F600\nM5\nX3\nM3 S30\nX4\nM3 S50\n"
    result = interpret(program, device)
    assert [s.pen_down for s in result.strokes] == ["M3 S20", "M3 S30"]
    assert [len(s.points) for s in result.strokes] == [2, 2]
    assert result.ignored == []


@pytest.mark.parametrize("name", ["hp7475a", "grbl"])
def test_interpret_gives_what_the_machine_gives_command_by_command(name):
    """interpret converts all strokes to sheet mm at once at the end; a machine executing one
    command (or line) at a time, as the simulators and resume do, converts each as the pen
    lifts: the same strokes and travels either way."""
    device = load_device(name)

    @settings(max_examples=20, deadline=None)
    @given(random_plans(device))
    def check(plan):
        program = write_program(plan, device)
        frame, text = device.frame(plan.sheet), program.text
        if device.protocol == "hpgl":
            machine = HPGLMachine(device, frame, program)
            tokenizer = HPGLTokenizer()
            for command in tokenizer.feed(text.encode("latin-1")) + tokenizer.close():
                machine.at = command.offset
                machine.execute(command)
        else:
            machine, offset = GcodeMachine(device, frame, program), 0
            for raw in text.split("\n"):
                machine.at = offset
                machine.execute(raw, offset, min(offset + len(raw) + 1, len(text)))
                offset += len(raw) + 1
        machine.at = len(text)
        stepwise, result = machine.finish(), interpret(program, device, plan.sheet)
        assert len(result.strokes) == len(stepwise.strokes) == len(expected_strokes(plan))
        for got, want in zip(result.strokes, stepwise.strokes):
            assert got.points.shape == want.points.shape and np.array_equal(got.points, want.points)
            assert (got.offset, got.end, got.pen, got.force, got.speed, got.pen_down, got.section) == \
                (want.offset, want.end, want.pen, want.force, want.speed, want.pen_down, want.section)
        assert [(t.start, t.end, t.next_stroke) for t in result.travels] == \
            [(t.start, t.end, t.next_stroke) for t in stepwise.travels]

    check()


def test_program_for_another_protocol_is_refused():
    from foldfab.errors import FoldfabError

    device = load_device("hp7475a")
    program = write_program(sample_plan(device), device)
    with pytest.raises(FoldfabError, match="hpgl program cannot run on grbl"):
        interpret(program, load_device("grbl"))


# --- estimate -------------------------------------------------------------------------


def test_move_times_trapezoid_and_triangle():
    # 100 mm at 50 mm/s, 500 mm/s^2: 0.1 s ramps, 5 mm each -> 90 mm cruise = 1.8 s + 0.2 s
    assert move_times(np.array([100.0]), 50, 500)[0] == pytest.approx(2.1)
    # 2 mm never reaches 50 mm/s: 2 * sqrt(2 / 500)
    assert move_times(np.array([2.0]), 50, 500)[0] == pytest.approx(2 * math.sqrt(2 / 500))


def test_straight_runs_merge_collinear_segments_only():
    points = np.array([[0, 0], [1, 0], [2, 0], [2, 0], [3, 0.001], [3, 5], [3, 0]])
    runs = straight_runs(points)
    assert runs.tolist() == pytest.approx([3.0000001666, 4.999, 5.0], rel=1e-6)


def test_estimate_keeps_strokes_apart():
    """Two strokes on one line, one after the other: each is its own straight move."""
    device = load_device("hp7475a")
    motion = device.motion
    strokes = [Stroke(np.array(points, dtype=float), 1, None, 10.0, None, 0)
               for points in ([[0, 0], [5, 0], [10, 0]], [[20, 0], [30, 0]], [[40, 0]])]
    run = Interpretation("hpgl", strokes, [Travel((10.0, 0.0), (20.0, 0.0), 1)])
    result = estimate(run, device)
    ten_mm = move_times(np.array([10.0]), 10.0, motion.acceleration)[0]
    assert result.draw_time == pytest.approx(2 * ten_mm)
    assert result.lower_bound == pytest.approx(2.0 + 6 * motion.pen_lift_time)
    pen = result.layers["pen 1"]
    assert (pen.drawn_length, pen.pen_lifts, pen.travel_length) == (20.0, 3, 10.0)


@pytest.mark.parametrize("name", DEVICES)
def test_estimate_is_the_sum_of_each_stroke_on_its_own(name):
    """Estimated for all strokes at once, it adds up what each stroke's points give alone."""
    device = load_device(name)
    motion = device.motion

    def alone(stroke: Stroke) -> float:
        if motion.junction_deviation is None:
            assert not motion.axis_limits  # (else each run's direction would count)
            return float(move_times(straight_runs(stroke.points), stroke.speed, motion.acceleration).sum())
        return float(planned_segments(stroke.points, np.zeros(1, dtype=np.intp), np.array([stroke.speed]),
                                      motion)[1].sum())

    @settings(max_examples=25, deadline=None)
    @given(random_plans(device))
    def check(plan):
        run = interpret(write_program(plan, device), device, plan.sheet)
        result = estimate(run, device)
        seconds = [alone(s) for s in run.strokes]
        assert result.draw_time == pytest.approx(sum(seconds), rel=1e-12, abs=1e-12)
        lower = sum(s.length / s.speed for s in run.strokes) + result.lift_time
        assert result.lower_bound == pytest.approx(lower, rel=1e-12, abs=1e-12)
        drawn: dict[str, float] = {}
        for stroke in run.strokes:
            drawn[stroke.layer] = drawn.get(stroke.layer, 0.0) + stroke.length
        assert {k: v.drawn_length for k, v in result.layers.items() if v.pen_lifts} == \
            pytest.approx(drawn, rel=1e-12, abs=1e-12)

    check()


def serpentine_plan(device: DeviceProfile, count: int = 10) -> tuple[PlotPlan, float]:
    """Long straight lines next to the park position, 2 mm apart, alternating direction."""
    frame = device.frame(device.sheet)
    along = device.sheet[0] if frame.matrix[0][0] else device.sheet[1]  # sheet size along x
    length = min(device.plottable_area[0], along) - 20
    rows = []
    for k in range(count):
        a, b = (10, 10 + 2 * k), (10 + length, 10 + 2 * k)
        rows.append(np.array([a, b] if k % 2 == 0 else [b, a]) * device.units_per_mm)
    lines = [frame.to_sheet(r) for r in rows]
    doc = make_document({1: [line[:, 0] + 1j * line[:, 1] for line in lines]})
    return PlotPlan(doc, [Pass(1, "cut", device.tool_for("cut"))], device.sheet), count * length


@pytest.mark.parametrize("name", DEVICES)
def test_estimate_close_to_lower_bound_on_long_straight_lines(name):
    device = load_device(name)
    plan, drawn = serpentine_plan(device)
    result = estimate(interpret(write_program(plan, device), device, plan.sheet), device)
    assert result.lower_bound <= result.total <= 1.1 * result.lower_bound
    speed = device.layers["cut"].speed
    assert result.lower_bound == pytest.approx(drawn / speed + 20 * device.motion.pen_lift_time)


@pytest.mark.parametrize("name", DEVICES)
def test_estimate_never_below_lower_bound(name):
    device = load_device(name)

    @settings(max_examples=25, deadline=None)
    @given(random_plans(device))
    def check(plan):
        result = estimate(interpret(write_program(plan, device), device, plan.sheet), device)
        assert result.total >= result.lower_bound - 1e-9
        layers = result.layers.values()
        assert sum(s.time for s in layers) == pytest.approx(result.total)
        assert sum(s.pen_lifts for s in layers) == len(expected_strokes(plan))

    check()


@settings(max_examples=300, deadline=None)
@given(st.text(alphabet="GXYZFMSPgxy0123456789.-+ \t();", max_size=30), st.integers(0, 10_000))
def test_reading_a_gcode_line_by_the_fast_paths_gives_what_the_full_scan_gives(raw, offset):
    """Lines without "(" or ";" skip the comment scan, lines of words only skip the scan for
    unreadable text, repeated lines come from a cache: none of it changes what is read."""
    import re

    from foldfab.programs.read_gcode import SUPPORTED_G, SUPPORTED_M, read_gcode_line

    word = re.compile(r"([A-Z])\s*([-+]?(?:\d+\.?\d*|\.\d+))")
    comment = re.compile(r"\(([^)]*)\)?|;(.*)$")
    code = comment.sub(" ", raw).upper()
    words = [(letter, float(number)) for letter, number in word.findall(code)]
    for _ in range(2):  # the second time from the cache
        line = read_gcode_line(raw, offset)
        assert (line.raw, line.offset, line.code) == (raw, offset, code)
        assert list(line.words) == words
        assert list(line.comments) == [a or b for a, b in comment.findall(raw)]
        assert line.unreadable == word.sub(" ", code).strip()
        assert list(line.unsupported) == [f"{k}{v:g}" for k, v in words if (k == "G" and v not in SUPPORTED_G)
                                          or (k == "M" and v not in SUPPORTED_M)]


_number = st.floats(-500, 500, allow_nan=False).map(lambda v: f"{v:.3f}".rstrip("0").rstrip("."))
_plain = st.one_of(st.tuples(_number, _number).map(lambda xy: f"X{xy[0]} Y{xy[1]}"),
                   st.tuples(_number, _number, st.integers(1, 3000)).map(lambda v: f"X{v[0]} Y{v[1]} F{v[2]}"))
_other = st.sampled_from(["G91", "G90", "G20", "G21", "G92 X0 Y0", "G92 X5", "G0", "G1", "(a comment)", "M0",
                          "x1 y2", "X1  Y2", "X.5 Y1", "X1 Y2 ; note", "Y4", "X2", "G1 X3 Y4 F900", "", "S10 X1 Y1"])
_pen = st.sampled_from(["G0 Z3", "G1 Z-0.3 F600", "G1 Z-1 F60"])
GCODE_LINES = st.lists(st.tuples(st.lists(_other, max_size=3), _pen, st.lists(st.one_of(_plain, _plain, st.just("(a comment)")), min_size=1, max_size=4)),
                       max_size=8).map(lambda blocks: [line for modes, pen, plain in blocks
                                                       for line in [*modes, pen, *plain]])
"""Programs in blocks: mode and other lines, a pen move, then plain coordinate lines among comments."""


@settings(max_examples=300, deadline=None)
@given(GCODE_LINES)
def test_plain_coordinate_lines_are_read_as_every_line_is(lines):
    """GcodeMachine takes a line of only X, Y and F words (most of a program) without reading
    its words one by one: the same strokes, travels, pauses and problems as the full reading,
    whatever modes (relative, inches, a pending G92) the lines before have set."""
    from foldfab.programs.read_gcode import read_gcode_line

    device, text = load_device("grbl"), "\n".join(lines)
    frame = device.frame(device.sheet)
    machine, offset = GcodeMachine(device, frame, None), 0
    machine.deferred = []
    for raw in text.split("\n"):
        machine.at = offset
        machine.apply(read_gcode_line(raw, offset), min(offset + len(raw) + 1, len(text)))
        offset += len(raw) + 1
    machine.at = len(text)
    full, fast = machine.finish(), interpret(text, device)
    assert [(s.points.tolist(), s.offset, s.end, s.speed, s.pen_down) for s in fast.strokes] == \
        [(s.points.tolist(), s.offset, s.end, s.speed, s.pen_down) for s in full.strokes]
    assert [(t.start, t.end, t.next_stroke) for t in fast.travels] == \
        [(t.start, t.end, t.next_stroke) for t in full.travels]
    assert [(p.message, p.position, p.offset) for p in fast.pauses] == \
        [(p.message, p.position, p.offset) for p in full.pauses]
    assert fast.ignored == full.ignored


# --- junction speeds (GRBL's planner) ---------------------------------------------------

GRBL = load_device("grbl")
A, JD = GRBL.motion.acceleration, GRBL.motion.junction_deviation
ONE_LIMIT = dataclasses.replace(GRBL.motion, axis_limits=False)
"""The grbl profile's motion with one speed and acceleration for every direction."""


def one_polyline(points, speed: float = 30.0, motion=ONE_LIMIT) -> np.ndarray:
    """Seconds of each non-zero segment of one polyline planned with junction speeds."""
    return planned_segments(np.asarray(points, dtype=float), np.zeros(1, dtype=np.intp),
                            np.array([speed]), motion)[1]


def grbl_junction(before, after, speed, acceleration, deviation) -> float:
    """GRBL 1.1 planner.c, one junction at a time (MINIMUM_JUNCTION_SPEED = 0)."""
    cos_theta = -(before[0] * after[0] + before[1] * after[1])
    if cos_theta > 0.999999:
        limit = 0.0
    elif cos_theta < -0.999999:
        limit = math.inf
    else:
        sin_theta_d2 = math.sqrt(0.5 * (1.0 - cos_theta))
        limit = acceleration * deviation * sin_theta_d2 / (1.0 - sin_theta_d2)
    return min(limit, speed * speed)


def grbl_passes(limits, lengths, acceleration) -> list[float]:
    """GRBL's backward then forward pass over squared speeds, one end at a time
    (``acceleration``: one, or one per move)."""
    n = len(lengths)
    a = list(acceleration) if isinstance(acceleration, list) else [acceleration] * n
    w = list(limits)
    for i in range(n - 1, -1, -1):
        w[i] = min(limits[i], w[i + 1] + 2 * a[i] * lengths[i])
    u = list(w)
    for i in range(1, n + 1):
        u[i] = min(w[i], u[i - 1] + 2 * a[i - 1] * lengths[i - 1])
    return u


coordinates = st.floats(-100, 100, allow_nan=False)
polylines = st.lists(st.tuples(coordinates, coordinates), min_size=2, max_size=12).filter(
    lambda p: len({(round(x, 6), round(y, 6)) for x, y in p}) > 1)
speeds = st.floats(1, 500)


def test_junction_speed_of_a_right_angle_by_hand():
    """90 degrees between two 100 mm segments at 30 mm/s (grbl: 500 mm/s², $11 = 0.01 mm)."""
    # cos θ = 0, sin(θ/2) = √½ = 0.70710678: v² = 500 · 0.01 · 0.70710678 / 0.29289322 = 12.0710678
    assert junction_limits((1.0, 0.0), (0.0, 1.0), 30.0, A, JD) == pytest.approx(12.0710678)
    assert junction_limits((1.0, 0.0), (1.0, 0.0), 30.0, A, JD) == 900.0  # straight: the speed
    assert junction_limits((1.0, 0.0), (-1.0, 0.0), 30.0, A, JD) == 0.0  # reversal: a stop
    # each segment: 0 -> 30 mm/s in 0.06 s over 0.9 mm; 30 -> 3.4743 mm/s (√12.0710678) in
    # 0.0530513 s over (900 - 12.0710678) / 1000 = 0.8879289 mm; the remaining 98.2120711 mm
    # at 30 mm/s take 3.2737357 s: 3.3867871 s, against 3.3933333 s from rest to rest
    times = one_polyline([(0, 0), (100, 0), (100, 100)])
    assert times.tolist() == pytest.approx([3.3867871, 3.3867871], abs=1e-7)
    assert move_times(np.array([100.0]), 30.0, A)[0] == pytest.approx(3.3933333, abs=1e-7)
    # a 2 mm segment between two right angles never reaches 30 mm/s: a triangle up to
    # v² = 12.0710678 + 500 · 2 = 1012.07 > 900, so 30 mm/s after all: 0.0530513 s each way
    # over 0.8879289 mm, 0.2241422 mm at 30 mm/s (0.0074714 s)
    times = one_polyline([(0, 0), (100, 0), (100, 2), (0, 2)])
    assert times[1] == pytest.approx(2 * 0.0530513 + 0.0074714, abs=1e-7)


@settings(max_examples=200, deadline=None)
@given(st.tuples(coordinates, coordinates), st.tuples(coordinates, coordinates), speeds, st.floats(1, 5000),
       st.floats(1e-4, 1.0))
def test_junction_limits_are_grbls(a, b, speed, acceleration, deviation):
    """The vectorised junction speeds are planner.c's, junction by junction."""
    before, after = np.array([a, b], dtype=float)
    if min(np.hypot(*before), np.hypot(*after)) < 1e-6:
        return
    before, after = before / np.hypot(*before), after / np.hypot(*after)
    expected = grbl_junction(before, after, speed, acceleration, deviation)
    got = junction_limits(np.array([before, after]), np.array([after, before]), speed, acceleration, deviation)
    assert got.tolist() == pytest.approx([expected] * 2, rel=1e-12)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.one_of(st.floats(0, 1e4), st.sampled_from([0.0, math.inf])),
                          st.one_of(st.floats(0, 50), st.just(0.0))), min_size=1, max_size=30),
       st.floats(1, 5000))
def test_vectorised_passes_are_grbls_loops(ends, acceleration):
    """plan_speeds (cumulative minima) gives what GRBL's two loops give."""
    limits = [limit for limit, _ in ends] + [0.0]
    lengths = [length for _, length in ends]
    limits[0] = 0.0
    expected = grbl_passes(limits, lengths, acceleration)
    got = plan_speeds(np.array(limits), np.array(lengths), acceleration)
    scale = 2 * acceleration * sum(lengths) + 1.0
    assert got.tolist() == pytest.approx(expected, abs=1e-12 * scale)
    assert (got >= 0).all()


@settings(max_examples=200, deadline=None)
@given(polylines, speeds)
def test_planned_time_between_the_bound_and_stopping_everywhere(points, speed):
    """No faster than the length at full speed, no slower than stopping at every vertex; the
    speeds at the ends stay within the junction limits and what acceleration can reach."""
    points = np.array(points, dtype=float)
    steps = np.diff(points, axis=0)
    lengths = np.hypot(*steps.T)
    steps, lengths = steps[lengths > 0], lengths[lengths > 0]
    total = float(one_polyline(points, speed).sum())
    assert lengths.sum() / speed * (1 - 1e-12) <= total
    assert total <= move_times(lengths, speed, A).sum() * (1 + 1e-12)
    units = steps / lengths[:, None]
    limits = np.concatenate([[0.0], junction_limits(units[:-1], units[1:], speed, A, JD), [0.0]])
    ends = plan_speeds(limits, lengths, A)
    slack = 1e-9 * (2 * A * lengths.sum() + speed * speed)
    assert (ends <= limits + slack).all() and ends[0] == 0.0 and ends[-1] == 0.0
    assert (ends[1:] <= ends[:-1] + 2 * A * lengths + slack).all()
    assert (ends[:-1] <= ends[1:] + 2 * A * lengths + slack).all()
    assert segment_times(lengths, speed, ends[:-1], ends[1:], A).sum() == total


@settings(max_examples=200, deadline=None)
@given(polylines, speeds)
def test_reversed_polyline_takes_as_long(points, speed):
    # A microsecond of slack: a segment of 2e-16 mm (a float's rounding of a point onto its
    # neighbour) takes about 1e-9 s, and its share of the rounding differs by direction.
    forward = one_polyline(points, speed).sum()
    assert one_polyline(points[::-1], speed).sum() == pytest.approx(forward, rel=1e-9, abs=1e-6)


@settings(max_examples=200, deadline=None)
@given(st.tuples(coordinates, coordinates), st.tuples(coordinates, coordinates),
       st.lists(st.integers(0, 1000), max_size=40), speeds)
def test_a_straight_line_split_into_points_takes_as_long_as_one_segment(a, b, cuts, speed):
    """(Pieces of a thousandth of the line at least: a piece of 1e-16 mm has no direction to
    speak of, and from rest to rest it would take 2 sqrt(L / a), 1e-9 s.)"""
    a, b = np.array(a), np.array(b)
    if np.hypot(*(b - a)) < 1e-3:
        return
    points = [a + t / 1000 * (b - a) for t in [0, *sorted(cuts), 1000]]
    whole = one_polyline([a, b], speed)
    assert one_polyline(points, speed).sum() == pytest.approx(whole.sum(), rel=1e-9)
    assert whole[0] == pytest.approx(move_times(np.array([np.hypot(*(b - a))]), speed, A)[0], rel=1e-12)


def test_junction_deviation_estimate_keeps_speed_through_corners():
    """On grbl (one limit for every direction), strokes that turn a little at every vertex go
    faster than from rest at each corner and never beat the bound; without $11 the same
    profile stops at corners."""
    from dataclasses import replace

    one = replace(GRBL, motion=ONE_LIMIT)
    stop = replace(one, motion=replace(ONE_LIMIT, junction_deviation=None))
    angles = np.linspace(0, math.pi, 60)
    arc = np.column_stack([100 + 50 * np.cos(angles), 100 + 50 * np.sin(angles)])
    run = Interpretation("gcode", [Stroke(arc, None, None, 30.0, -0.3, 0)], [])
    planned, stopping = estimate(run, one), estimate(run, stop)
    assert planned.lower_bound <= planned.total < stopping.total
    assert planned.draw_time == pytest.approx(one_polyline(arc).sum(), rel=1e-12)
    # turns of 3 degrees pass at full speed (v² = 14,000 > 900): the stroke ramps at its ends only
    chords = 59 * 100 * math.sin(math.pi / 118)
    assert planned.draw_time == pytest.approx(move_times(np.array([chords]), 30.0, A)[0], rel=1e-12)


# --- per-axis limits (GRBL's $110/$111, $120/$121) ----------------------------------------


def test_axis_factors_by_hand():
    assert axis_factors(np.array([[1.0, 0.0], [0.0, -2.0], [1.0, 1.0], [3.0, -4.0], [0.0, 0.0]])).tolist() == \
        pytest.approx([1.0, 1.0, math.sqrt(2), 1.25, 1.0])


def test_a_diagonal_pen_up_move_is_faster_by_the_square_root_of_two():
    """On grbl, 100 mm along an axis take what one limit gives; 100 mm at 45 degrees as if
    speed and acceleration were both 1.41 times the profile's."""
    motion = GRBL.motion
    v, a = motion.travel_speed, motion.acceleration
    run = Interpretation("gcode", [], [Travel((0.0, 0.0), (100.0, 0.0), 0),
                                       Travel((100.0, 0.0), (100 + 50 * math.sqrt(2), 50 * math.sqrt(2)), 0)])
    per_axis = estimate(run, GRBL).travel_time
    single = estimate(run, replace_motion(GRBL, axis_limits=False)).travel_time
    one = float(move_times(np.array([100.0]), v, a)[0])
    diagonal = float(move_times(np.array([100.0]), v * math.sqrt(2), a * math.sqrt(2))[0])
    assert per_axis == pytest.approx(one + diagonal) and diagonal < one
    assert single == pytest.approx(2 * one)


def replace_motion(device: DeviceProfile, **changes) -> DeviceProfile:
    return dataclasses.replace(device, motion=dataclasses.replace(device.motion, **changes))


def grbl_axis_limit(settings: float, unit) -> float:
    """planner.c's limit_value_by_axis_maximum for equal settings on both axes (a share too
    small to divide by gives no limit, as in C)."""
    return min(settings / abs(float(u)) if abs(u) > 1e-300 else math.inf for u in unit if u)


@settings(max_examples=200, deadline=None)
@given(polylines, st.floats(1, 200))
def test_per_axis_planning_is_grbls(points, feed):
    """With axis_limits, each segment's acceleration and rapid cap, and each junction's
    acceleration (along the difference of the unit vectors), are planner.c's."""
    motion = GRBL.motion
    # A program's coordinates have three decimals: points closer than a micrometre never reach
    # the planner (GRBL drops a move of no steps), and there the two sides' rounding differs
    # by a nanosecond (a 2e-16 mm step: 1.3e-9 against 0.9e-9 s).
    kept = [points[0]]
    for point in points[1:]:
        if math.dist(point, kept[-1]) == 0 or math.dist(point, kept[-1]) >= 1e-6:
            kept.append(point)
    points = np.array(kept, dtype=float)
    steps = np.diff(points, axis=0)
    steps = steps[np.hypot(*steps.T) > 0]
    lengths = np.hypot(*steps.T)
    units = steps / lengths[:, None]
    accelerations = [grbl_axis_limit(motion.acceleration, u) for u in units]
    nominal = [min(feed, grbl_axis_limit(motion.travel_speed, u)) for u in units]
    limits = [0.0]
    for i in range(1, len(units)):
        turn = units[i] - units[i - 1]
        turn_a = grbl_axis_limit(motion.acceleration, turn / np.hypot(*turn)) if np.hypot(*turn) > 1e-12 \
            else motion.acceleration
        limits.append(grbl_junction(units[i - 1], units[i], min(nominal[i - 1], nominal[i]), turn_a,
                                    motion.junction_deviation))
    limits.append(0.0)
    ends = grbl_passes(limits, lengths.tolist(), accelerations)
    expected = segment_times(lengths, np.array(nominal), np.array(ends[:-1]), np.array(ends[1:]),
                             np.array(accelerations))
    got = one_polyline(points, feed, GRBL.motion)
    assert got.tolist() == pytest.approx(expected.tolist(), rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("name", ["grbl"])
def test_per_axis_limits_never_make_a_plot_slower(name):
    """Per-axis limits give every move at least the one limit's speed and acceleration (with
    draw speeds under the travel speed): the estimate never grows, and never beats the bound."""
    device = load_device(name)
    one = replace_motion(device, axis_limits=False)

    @settings(max_examples=25, deadline=None)
    @given(random_plans(device))
    def check(plan):
        run = interpret(write_program(plan, device), device, plan.sheet)
        per_axis, single = estimate(run, device), estimate(run, one)
        assert per_axis.lower_bound <= per_axis.total <= single.total * (1 + 1e-12)
        assert per_axis.travel_time <= single.travel_time * (1 + 1e-12)

    check()


@pytest.mark.parametrize("value, words", [
    ("-0.01", ["motion.junction_deviation", "mm > 0", "-0.01"]),
    ("0", ["motion.junction_deviation", "mm > 0"]),
    ('"small"', ["motion.junction_deviation", "mm > 0", "'small'"]),
])
def test_junction_deviation_is_checked(tmp_path, value, words):
    from foldfab.errors import FoldfabError

    path = tmp_path / "bad.toml"
    path.write_text(Path(GRBL.source).read_text().replace("junction_deviation = 0.01",
                                                          f"junction_deviation = {value}"))
    with pytest.raises(FoldfabError) as error:
        load_device(str(path))
    message = str(error.value)
    assert str(path) in message and all(word in message for word in words), message
    hp = Path(load_device("hp7475a").source).read_text()
    path.write_text(hp.replace("[motion]", "[motion]\njunction_deviation = 0.01"))
    with pytest.raises(FoldfabError, match="motion.junction_deviation.*no junction_deviation"):
        load_device(str(path))
