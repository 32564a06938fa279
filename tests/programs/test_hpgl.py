"""HPGL writer: round trips for every HPGL device, compactness, dialects, guard, hp2xx."""

from __future__ import annotations

import copy
import shutil
import subprocess
from dataclasses import replace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from foldfab.devices import load_device
from foldfab.errors import FoldfabError
from foldfab.programs.hpgl import write_hpgl
from foldfab.programs.read_hpgl import HPGLTokenizer
from foldfab.devices import Tool
from foldfab.fabrication.plan import Pass, PlotPlan
from foldfab.programs.languages import write_program
from helpers.plans import assert_round_trip, make_document, random_plans, sample_plan

HPGL_DEVICES = ["hp7475a", "graphtec-ce6000", "roland-gx24"]


def commands(text: str):
    tokenizer = HPGLTokenizer()
    return tokenizer.feed(text.encode("ascii")) + tokenizer.close()


@pytest.mark.parametrize("name", HPGL_DEVICES)
def test_round_trip_sample(name):
    device = load_device(name)
    plan = sample_plan(device)
    program = write_hpgl(plan, device)
    assert program == write_program(plan, device)
    assert_round_trip(plan, device, program)


@pytest.mark.parametrize("name", HPGL_DEVICES)
def test_round_trip_random(name):
    device = load_device(name)

    @settings(max_examples=40, deadline=None)
    @given(random_plans(device))
    def check(plan):
        assert_round_trip(plan, device, write_hpgl(plan, device))

    check()


@pytest.mark.parametrize("name", HPGL_DEVICES)
def test_deterministic(name):
    device = load_device(name)
    plan = sample_plan(device)
    assert write_hpgl(plan, device) == write_hpgl(copy.deepcopy(plan), device)


@pytest.mark.parametrize("name", HPGL_DEVICES)
def test_compact_encoding(name):
    """IN first; SP/FS/VS only on change; one PU + one chained PD per line; integers; park."""
    device = load_device(name)
    plan = sample_plan(device, mountain_passes=3)
    text = write_hpgl(plan, device).text
    assert text.startswith("IN;") and text.endswith(";SP0;") and "\n" not in text
    cmds = commands(text)
    state = {"SP": None, "FS": None, "VS": None}
    for command in cmds:
        if command.name in state:
            assert command.params != state[command.name], f"redundant {command.name}"
            state[command.name] = command.params
        if command.name in ("PU", "PD"):
            assert all(v == int(v) for v in command.params)
    lines = sum(len(plan.document.layers[s.layer_id]) * s.tool.passes
                for s in plan.steps if isinstance(s, Pass))
    assert sum(c.name == "PD" for c in cmds) == lines
    assert sum(c.name == "PU" for c in cmds) == lines + 2  # + park at the pause and the end
    park = [round(v * device.units_per_mm) for v in device.motion.park]
    assert [c.name for c in cmds[-2:]] == ["PU", "SP"] and list(cmds[-2].params) == park


def longest_instruction(text: str) -> int:
    return max(len(instruction) + 1 for instruction in text.split(";")[:-1])


def with_buffer(device, size: int):
    return replace(device, buffer=replace(device.buffer, size=size))


@pytest.mark.parametrize("name", HPGL_DEVICES)
def test_pd_lists_are_split_to_fit_small_buffers(name):
    """Buffers from 32 bytes up: no instruction longer than the buffer allows, same strokes."""
    device = load_device(name)

    @settings(max_examples=30, deadline=None)
    @given(random_plans(device), st.integers(32, 400))
    def check(plan, size):
        small = with_buffer(device, size)
        program = write_hpgl(plan, small)
        assert longest_instruction(program.text) <= max(size // 2, min(24, size - 3))
        assert_round_trip(plan, small, program)

    check()


def test_a_buffer_too_small_for_one_coordinate_pair_is_refused():
    device = with_buffer(load_device("hp7475a"), 12)
    doc = make_document({1: [[100 + 100j, 150 + 100j, 150 + 150j]]})
    plan = PlotPlan(doc, [Pass(1, "valley", device.tool_for("valley"))], device.sheet)
    with pytest.raises(FoldfabError, match=r"12-byte buffer \(\[buffer\] size\).*at least"):
        write_hpgl(plan, device)


def test_dialects_encode_force_and_speed():
    hp = load_device("hp7475a")
    doc = make_document({1: [[30 + 30j, 60 + 30j]]})
    plan = PlotPlan(doc, [Pass(1, "valley", hp.tool_for("valley", {"speed": 55.5}))], hp.sheet)
    assert "VS5.55;" in write_hpgl(plan, hp).text and "FS" not in write_hpgl(plan, hp).text
    graphtec = load_device("graphtec-ce6000")
    plan = PlotPlan(doc, [Pass(1, "cut", graphtec.tool_for("cut"))], graphtec.sheet)
    assert write_hpgl(plan, graphtec).text.startswith("IN;SP1;FS18;VS10;PU")
    roland = load_device("roland-gx24")
    plan = PlotPlan(doc, [Pass(1, "cut", roland.tool_for("cut", {"force": 150}))], roland.sheet)
    assert write_hpgl(plan, roland).text.startswith("IN;SP1;FS150;VS10;PU")


@pytest.mark.parametrize("tool, key, words", [
    (Tool(1, 18, 25.0), "tool.speed", "multiple of 10 mm/s"),
    (Tool(1, 60, 100.0), "tool.force", "[1, 38]"),
    (Tool(9, 18, 100.0), "tool.pen", "[1, 8]"),
])
def test_tools_the_device_cannot_express_are_refused(tool, key, words):
    device = load_device("graphtec-ce6000")
    plan = PlotPlan(make_document({1: [[30 + 30j, 60 + 30j]]}), [Pass(1, "cut", tool)], device.sheet)
    with pytest.raises(FoldfabError) as error:
        write_hpgl(plan, device)
    assert "plan step 1 (cut pass)" in str(error.value) and key in str(error.value)
    assert words in str(error.value)


def test_force_on_a_pen_plotter_is_refused():
    device = load_device("hp7475a")
    plan = PlotPlan(make_document({1: [[30 + 30j, 60 + 30j]]}), [Pass(1, "cut", Tool(1, 50, 100.0))],
                    device.sheet)
    with pytest.raises(FoldfabError, match="tool.force.*no force"):
        write_hpgl(plan, device)


def test_pause_is_an_offset_after_parking():
    device = load_device("hp7475a")
    plan = sample_plan(device)
    program = write_hpgl(plan, device)
    (pause,) = program.pauses
    park = "PU{},{};SP0;".format(*(round(v * device.units_per_mm) for v in device.motion.park))
    assert program.text[:pause.offset].endswith(park)
    assert program.text[pause.offset:].startswith("SP2;")
    assert pause.message == plan.steps[1].message and pause.step == 1


def test_tool_change_pauses_on_a_cutter_without_changer():
    device = load_device("graphtec-ce6000")
    doc = make_document({1: [[30 + 30j, 60 + 30j]], 2: [[30 + 40j, 60 + 40j]]})
    plan = PlotPlan(doc, [Pass(1, "valley", device.tool_for("valley")),
                          Pass(2, "cut", device.tool_for("cut", {"pen": 2}))], device.sheet)
    program = write_hpgl(plan, device)
    assert [p.message for p in program.pauses] == ["Load tool 2 for the cut pass, then resume."]
    assert program.text[program.pauses[0].offset:].startswith("SP2;")
    # the HP 7475A changes pens itself: no pause
    hp = load_device("hp7475a")
    plan = PlotPlan(doc, [Pass(1, "valley", hp.tool_for("valley")),
                          Pass(2, "cut", hp.tool_for("cut"))], hp.sheet)
    assert write_hpgl(plan, hp).pauses == ()


@pytest.mark.parametrize("name, sheet, corners, design, usable, area, scale", [
    ("hp7475a", None, (0, 297 + 210j), "297.0 x 210.0", "x 10.0..284.0, y 14.0..206.0",
     "274 x 192", "0.914"),
    ("graphtec-ce6000", [400, 500], (10 + 10j, 390 + 490j), "380.0 x 480.0",
     "x 25.0..400.0, y 0.0..500.0", "1000 x 375", "0.987"),
])
def test_out_of_area_guard(name, sheet, corners, design, usable, area, scale):
    device = load_device(name)
    a, b = corners
    doc = make_document({1: [[a, complex(b.real, a.imag), b, complex(a.real, b.imag), a]]})
    plan = PlotPlan(doc, [Pass(1, "cut", device.tool_for("cut"))], tuple(sheet or device.sheet))
    with pytest.raises(FoldfabError) as error:
        write_hpgl(plan, device)
    message = str(error.value)
    for part in (f"design is {design} mm", usable, f"plottable area {area} mm",
                 f"largest scale that fits: {scale}"):
        assert part in message


def test_guard_refuses_a_design_that_fits_but_lies_outside():
    device = load_device("hp7475a")
    doc = make_document({1: [[2 + 100j, 50 + 100j]]})  # x < 10 mm is out of reach
    plan = PlotPlan(doc, [Pass(1, "cut", device.tool_for("cut"))], device.sheet)
    with pytest.raises(FoldfabError, match="largest scale that fits: 5.708; it fits at scale 1: move"):
        write_hpgl(plan, device)


@pytest.mark.parametrize("name", HPGL_DEVICES)
def test_hp2xx_reads_our_hpgl(name, tmp_path):
    """An independent reader accepts our HPGL (never skipped: .ci/run installs hp2xx)."""
    assert shutil.which("hp2xx"), "hp2xx is missing: apt-get install hp2xx (.ci/run does)"
    device = load_device(name)
    source = tmp_path / "plot.hpgl"
    source.write_text(write_hpgl(sample_plan(device), device).text)
    run = subprocess.run(["hp2xx", "-q", "-m", "svg", "-f", str(tmp_path / "plot.svg"), str(source)],
                         capture_output=True, text=True, timeout=60)
    assert (run.returncode, run.stdout, run.stderr) == (0, "", "")
    assert "<path" in (tmp_path / "plot.svg").read_text()
