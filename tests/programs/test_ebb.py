"""EBB writer and reader: round trips on both AxiDraw profiles (sample, random and every example
job), the commands as the firmware takes them, the motion's limits, and the reader's hostile cases."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings

from foldfab.design import load_design
from foldfab.devices import load_device
from foldfab.fabricate import fabricate
from foldfab.programs.ebb import VERTEX_MARK, write_ebb
from foldfab.programs.estimate import estimate
from foldfab.programs.interpret import interpret, pen_states
from foldfab.programs.languages import write_program
from foldfab.programs.read_ebb import ebb_commands
from helpers import JOBS
from helpers.plans import assert_round_trip, random_plans, sample_plan, spec

AXIDRAWS = ["axidraw-v3", "axidraw-se-a3"]


def commands(text: str):
    return [command for command, _ in ebb_commands(text)]


@pytest.mark.parametrize("name", AXIDRAWS)
def test_round_trip_sample(name):
    device = load_device(name)
    plan = sample_plan(device)
    program = write_ebb(plan, device)
    assert program == write_program(plan, device)
    assert_round_trip(plan, device, program)


@pytest.mark.parametrize("name", AXIDRAWS)
def test_round_trip_random(name):
    device = load_device(name)

    @settings(max_examples=40, deadline=None)
    @given(random_plans(device))
    def check(plan):
        assert_round_trip(plan, device, write_ebb(plan, device))

    check()


@pytest.mark.parametrize("name", AXIDRAWS)
@pytest.mark.parametrize("job", JOBS, ids=[j.stem for j in JOBS])
def test_round_trip_every_job(job, name):
    """Every crease and the outline of every example job come back within one motor step."""
    device = load_device(name)
    fab = fabricate(load_design(job), device, spec(sheet=" ".join(("A4" if name == "axidraw-v3" else "A3",
                                                                    "landscape")), scale="fit"))
    assert_round_trip(fab.plan, device, fab.program)
    assert 0.5 / device.units_per_mm * math.sqrt(2) < device.resolution  # the tolerance used: < 1 step
    run = interpret(fab.program, device, fab.plan.sheet)
    assert [s.layer for s in run.strokes][-1] == "cut"


@pytest.mark.parametrize("name", AXIDRAWS)
def test_commands_as_the_firmware_takes_them(name):
    """Setup from the profile (EM, SC 4/5/11/12, SP), then only SP and SM; every SM within the
    board's limits; the motors' step counts end at the park position."""
    device = load_device(name)
    program = write_ebb(sample_plan(device), device)
    text = program.text
    assert text.endswith("\r") and "\n" not in text and text.isascii()
    cmds = commands(text)
    ebb = device.ebb
    assert [(c.name, c.args) for c in cmds[:6]] == [
        ("EM", (1, 1)), ("SC", (4, 20641)), ("SC", (5, 15248)), ("SC", (11, 1618)), ("SC", (12, 1079)),
        ("SP", (1, 150))]
    assert ebb.position(60) == 20641 and ebb.rate(75) == 1618  # AxiDraw's own numbers for its defaults
    assert {c.name for c in cmds[6:]} == {"SP", "SM"}
    m1 = m2 = 0
    for c in cmds:
        if c.name == "SM":
            ms, s1, s2 = c.args
            assert 1 <= ms <= round(ebb.time_slice * 1000) + 1
            assert max(abs(s1), abs(s2)) / ms <= 25  # 25 kHz: the EBB's highest step rate
            m1, m2 = m1 + s1, m2 + s2
    assert (m1, m2) == (0, 0)
    pen = [c.args[0] for c in cmds if c.name == "SP"]
    assert all(a != b for a, b in zip(pen, pen[1:])), "a redundant SP"


@pytest.mark.parametrize("name", AXIDRAWS)
def test_moves_accelerate_at_the_profile_rate(name):
    """Each move's slices speed up and slow down at no more than the profile's acceleration (with
    the rounding of steps and milliseconds), and cruise at no more than the layer's speed."""
    device = load_device(name)
    text = write_ebb(sample_plan(device), device).text
    scale, accel = device.units_per_mm, device.motion.acceleration
    speeds = []
    for c in commands(text):
        if c.name == "SM" and (c.args[1] or c.args[2]):
            ms, s1, s2 = c.args
            speeds.append(math.hypot((s1 + s2) / 2, (s1 - s2) / 2) / scale / (ms / 1000))
        else:
            speeds.append(0.0)
    speeds = np.asarray(speeds)
    assert speeds.max() <= device.motion.travel_speed * 1.06
    slice_s = device.ebb.time_slice
    assert np.abs(np.diff(speeds)).max() <= accel * slice_s * 1.5 + 2 / scale / slice_s


@pytest.mark.parametrize("name", AXIDRAWS)
def test_estimate_matches_the_programs_own_durations(name):
    """The time estimate (rest to rest at every corner) agrees with the sum of the SM durations
    and SP delays the program itself holds, within the millisecond rounding."""
    device = load_device(name)
    program = write_ebb(sample_plan(device), device)
    cmds = commands(program.text)
    moving = sum(c.args[0] for c in cmds if c.name == "SM" and c.args[1:] != (0, 0)) / 1000
    lifts = sum(c.args[1] for c in cmds[6:] if c.name == "SP") / 1000
    guess = estimate(interpret(program, device), device)
    assert guess.draw_time + guess.travel_time == pytest.approx(moving, rel=0.02)
    assert guess.lift_time == pytest.approx(lifts, abs=0.2)


def test_vertices_are_marked_and_a_stream_without_marks_keeps_every_move():
    device = load_device("axidraw-v3")
    program = write_ebb(sample_plan(device), device)
    marked = interpret(program.text, device)
    unmarked = interpret(program.text.replace(VERTEX_MARK, ""), device)
    assert len(marked.strokes) == len(unmarked.strokes)
    for a, b in zip(marked.strokes, unmarked.strokes):
        assert len(b.points) > len(a.points)
        assert np.allclose(a.points[-1], b.points[-1]) and a.length == pytest.approx(b.length, abs=0.05)


@pytest.mark.parametrize("text, ignored", [
    ("SM,10,5\rXM,10,3,1\r", []),
    ("SM,a,b\r", ["SM at byte 0: cannot read arguments 'SM,a,b'"]),
    ("ZZ,1\rSP,7\r", ["ZZ at byte 0", "SP at byte 5"]),
    ("SM,0,100,100\r", ["SM at byte 0"]),
    ("\r\r\n\n", []),
    ("SP,0\rSM,10,4,4\rTP\rSM,10,-4,-4\r" * 3, []),
    ("SM," + "9" * 5000 + ",1\r", ["SM at byte 0: cannot read arguments 'SM," + "9" * 37 + "'"]),
    ("SM,10,2147483648,0\r", ["SM at byte 0: cannot read arguments 'SM,10,2147483648,0'"]),
])
def test_hostile_text_is_read_without_crashing(text, ignored):
    device = load_device("axidraw-v3")
    run = interpret(text, device)
    assert run.ignored == ignored
    assert sum(1 for _ in pen_states(text, "ebb", device)) >= 1


def test_xm_moves_the_head_along_the_axes():
    device = load_device("axidraw-v3")
    run = interpret("SP,0\rXM,10,80,0\rSM,1,0,0\rXM,10,0,160\rSP,1\r", device)
    assert np.allclose(run.strokes[0].points, [[0, 0], [1, 0], [1, 2]])


def test_an_ebb_profile_needs_its_table(tmp_path):
    from foldfab.errors import FoldfabError

    text = open(load_device("axidraw-v3").source).read()
    for old, new, words in [
        ("[ebb]", "[ebbx]", "unknown key"),
        ("pen_down = 30 ", "pen_down = 60 ", "a height other than pen_up"),
        ('flow_control = "ebb"', 'flow_control = "none"', "buffer.flow_control"),
        ("travel_speed = 150.6", "travel_speed = 400", "at most 221.0 mm/s"),
        ("microstepping = 1 ", "microstepping = 9 ", "an EM mode 1..5"),
    ]:
        path = tmp_path / "bad.toml"
        path.write_text(text.replace(old, new))
        with pytest.raises(FoldfabError, match=words):
            load_device(str(path))
    grbl = open(load_device("grbl").source).read() + "\n[ebb]\npen_up = 1\n"
    path = tmp_path / "grbl.toml"
    path.write_text(grbl)
    with pytest.raises(FoldfabError, match=r"no \[ebb\] table in a gcode profile"):
        load_device(str(path))


def test_a_long_travel_keeps_every_command():
    """A move of thousands of time slices (more than the writer joins into one block) arrives
    whole: the motors' steps add up to the target."""
    from dataclasses import replace

    from foldfab.programs.ebb import _motor_steps, travel

    device = load_device("axidraw-v3")
    device = replace(device, ebb=replace(device.ebb, time_slice=0.001))
    park, target = np.asarray(device.park_units, dtype=float), np.asarray([9000.0, 6000.0])
    text = travel(device, target)
    moves = [command.split(",") for command in text.split("\r")[:-1]]
    assert len(moves) > 1024 and all(move[0] == "SM" for move in moves)
    steps = np.sum([[int(move[2]), int(move[3])] for move in moves], axis=0)   # SM,ms,motor 1,motor 2
    assert steps.tolist() == (_motor_steps(target) - _motor_steps(park)).tolist()
