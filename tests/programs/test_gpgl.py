"""GP-GL: the writer's round trips on every GP-GL profile and example job, its encoding, the
reader's tokenizer, the profiles' [gpgl] and [media] tables and a job's media preset."""

from __future__ import annotations

import copy
import re
from dataclasses import replace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from foldfab.design import load_design
from foldfab.devices import load_device
from foldfab.errors import FoldfabError
from foldfab.fabricate import fabricate
from foldfab.fabrication.plan import Pass
from foldfab.programs.gpgl import write_gpgl
from foldfab.programs.interpret import interpret
from foldfab.programs.languages import write_program
from foldfab.programs.read_gpgl import GPGLTokenizer, tokenize, tool_state
from helpers import GPGL_DEVICES, HEXAGON, JOBS, ROOT
from helpers.plans import assert_round_trip, random_plans, sample_plan, spec


@pytest.mark.parametrize("name", GPGL_DEVICES)
def test_round_trip_sample(name):
    device = load_device(name)
    plan = sample_plan(device)
    program = write_gpgl(plan, device)
    assert program == write_program(plan, device)
    assert_round_trip(plan, device, program)


@pytest.mark.parametrize("name", GPGL_DEVICES)
def test_round_trip_random(name):
    device = load_device(name)

    @settings(max_examples=40, deadline=None)
    @given(random_plans(device))
    def check(plan):
        assert_round_trip(plan, device, write_gpgl(plan, device))

    check()


@pytest.mark.parametrize("name", GPGL_DEVICES)
@pytest.mark.parametrize("job", JOBS, ids=[j.stem for j in JOBS])
def test_every_example_job_comes_back_on_its_tool_and_force(job, name):
    """Every crease and the outline, each on its pass's tool holder, force and speed, within
    one device unit (the plan is the crease pattern placed: test_fabrication checks that)."""
    device = load_device(name)
    fab = fabricate(load_design(job), device, spec())
    assert_round_trip(fab.plan, device, fab.program)
    tools = {s.name: s.tool for s in fab.plan.steps if isinstance(s, Pass)}
    assert tools["valley"].pen == device.layers["valley"].pen and tools["cut"].pen == device.layers["cut"].pen


def test_the_cameo_scores_with_tool_2_and_cuts_with_tool_1_in_one_job():
    device = load_device("silhouette-cameo-4")
    fab = fabricate(load_design(HEXAGON), device)
    run = interpret(fab.program, device)
    assert fab.program.pauses == () and run.pauses == []  # J changes the holder: no operator pause
    assert {(s.layer, s.pen) for s in run.strokes} == {("valley", 2), ("mountain", 2), ("cut", 1)}
    assert re.findall(r"J\d", fab.program.text) == ["J2", "J1"]
    assert "FC0,1,2\x03" in fab.program.text and "FC18,1,1\x03" in fab.program.text  # 0.9 mm blade


def test_the_portrait_scores_at_low_force_and_cuts_at_high_force():
    device = load_device("silhouette-portrait-3")
    fab = fabricate(load_design(JOBS[1]), device, spec())
    run = interpret(fab.program, device, fab.plan.sheet)
    forces = {s.layer: s.force for s in run.strokes}
    assert {s.pen for s in run.strokes} == {1} and "J" not in fab.program.text
    assert forces["valley"] == forces["mountain"] < forces["cut"]


@pytest.mark.parametrize("name", GPGL_DEVICES)
def test_encoding(name):
    """Initialise first, every command ended by ETX, whole units, settings only on change, one M
    and a D per point for each line, park at the end."""
    device = load_device(name)
    plan = sample_plan(device, mountain_passes=3)
    text = write_gpgl(plan, device).text
    assert text.startswith("\x1b\x04FN0\x03TB50,0\x03\\0,0\x03Z") and text.endswith("\x03")
    commands = tokenize(text)
    assert [c.name for c in commands[:5]] == ["ESC04", "FN", "TB", "\\", "Z"]
    assert list(commands[4].params) == [round(v * device.units_per_mm) for v in device.plottable_area]
    assert all(c.error is None for c in commands)
    state = {}
    for command in commands:
        if command.name in ("FX", "!", "J"):
            assert state.get(command.name) != command.params, f"redundant {command.name}"
            state[command.name] = command.params
        if command.name in ("M", "D"):
            assert len(command.params) == 2 and all(v == int(v) for v in command.params)
    lines = sum(len(plan.document.layers[s.layer_id]) * s.tool.passes for s in plan.steps if isinstance(s, Pass))
    points = sum(len(line) * s.tool.passes for s in plan.steps if isinstance(s, Pass)
                 for line in plan.document.layers[s.layer_id])
    assert sum(c.name == "M" for c in commands) == lines + 2  # + park at the pause and the end
    assert sum(c.name == "D" for c in commands) == points  # one per point: the first lowers the tool there
    assert list(commands[-1].params) == list(device.park_units)


@pytest.mark.parametrize("name", GPGL_DEVICES)
def test_deterministic(name):
    device = load_device(name)
    plan = sample_plan(device)
    assert write_gpgl(plan, device) == write_gpgl(copy.deepcopy(plan), device)


@given(st.lists(st.integers(1, 40), max_size=30))
@settings(max_examples=60, deadline=None)
def test_the_tokenizer_gives_the_same_commands_however_the_stream_is_cut(cuts):
    device = load_device("silhouette-cameo-4")
    data = write_gpgl(sample_plan(device), device).encode() + b"FX3\x1b\x05,1\x03"
    whole = GPGLTokenizer().feed(data)
    tokenizer, pieces, start = GPGLTokenizer(), [], 0
    for size in cuts:
        pieces += tokenizer.feed(data[start:start + size])
        start += size
    pieces += tokenizer.feed(data[start:])
    assert pieces == whole
    assert [c.name for c in whole[-2:]] == ["ESC05", "FX"] and whole[-1].params == (3.0, 1.0)  # ESC inside


@pytest.mark.parametrize("text, ignored", [
    ("M1,2,3\x03", "odd coordinate count"),
    ("D1;2\x03", "cannot read parameters"),
    ("12,3\x03", "no mnemonic"),
    ("QQ5\x03", "QQ"),
    ("\x00\xff\x03", "no mnemonic"),
])
def test_hostile_commands_are_reported_not_drawn(text, ignored):
    device = load_device("silhouette-cameo-4")
    run = interpret(text.encode("latin-1").decode("latin-1"), device)
    assert any(ignored in line for line in run.ignored) and run.strokes == []


def test_a_d_where_the_tool_stands_lowers_it_and_a_d_elsewhere_draws_from_there():
    device = load_device("silhouette-cameo-4")
    run = interpret("M20,20\x03D20,20\x03M40,40\x03D60,40\x03D60,60\x03H\x03", device)
    assert [len(s.points) for s in run.strokes] == [1, 3]
    assert run.travels[-1].end == pytest.approx(tuple(device.frame(device.sheet).to_sheet([(0, 0)])[0]))


def test_tool_state_restores_the_last_setting_of_each_holder():
    text = "\x1b\x04J2\x03FX12,2\x03!10,2\x03FC0,1,2\x03J1\x03FX27,1\x03!5,1\x03FC18,1,1\x03FX25,1\x03"
    assert tool_state(text) == "FX12,2\x03!10,2\x03FC0,1,2\x03J1\x03!5,1\x03FC18,1,1\x03FX25,1\x03"
    assert tool_state(text + "\x1b\x04") == ""


# --- profiles ----------------------------------------------------------------------------------------


def test_gpgl_profiles_load():
    cameo = load_device("silhouette-cameo-4")
    assert (cameo.protocol, cameo.dialect, cameo.units_per_mm, cameo.buffer.flow_control) == \
        ("gpgl", "graphtec", 20.0, "status")
    assert cameo.gpgl.blade_offset == (0.9, 0.0) and cameo.tool_changer
    assert set(cameo.media) == {"copy-paper", "card-160", "card-300"}
    assert load_device("silhouette-portrait-3").gpgl.tools == 1


def edited(tmp_path, old: str, new: str, name="silhouette-cameo-4"):
    text = (ROOT / "devices" / f"{name}.toml").read_text()
    assert old in text
    path = tmp_path / "edited.toml"
    path.write_text(text.replace(old, new))
    return str(path)


@pytest.mark.parametrize("old, new, words", [
    ("[gpgl]\nblade_offset = [0.9, 0.0]", "", r"missing table '\[gpgl\]'"),
    ("blade_offset = [0.9, 0.0]", "blade_offset = [0.9, 9]", r"key 'gpgl.blade_offset': expected a list of 1 to 8"),
    ("blade_offset = [0.9, 0.0]", "blade_offset = [0.9]", r"key 'layers.valley.pen': expected a tool holder from 1 to 1"),
    ('flow_control = "status"', 'flow_control = "none"', r"key 'buffer.flow_control': expected a flow control for gpgl"),
    ("score = { force = 12, speed = 100, passes = 1 }", "score = { force = 40 }",
     r"key 'media.card-160.score.force': expected a value in \[1, 33\]"),
    ("score = { force = 12, speed = 100, passes = 1 }", "score = { speed = 105 }",
     r"key 'media.card-160.score.speed': expected a multiple of 10"),
    ("score = { force = 12, speed = 100, passes = 1 }", "score = { pressure = 3 }",
     r"unknown key 'media.card-160.score.pressure'"),
    ('description = "card, 160 g/m²"\n', 'description = "card, 160 g/m²"\ncolour = 1\n',
     r"unknown key 'media.card-160.colour'"),
])
def test_gpgl_and_media_schema_errors_name_file_and_key(tmp_path, old, new, words):
    with pytest.raises(FoldfabError, match=words):
        load_device(edited(tmp_path, old, new))


def test_a_gpgl_table_is_refused_in_an_hpgl_profile(tmp_path):
    text = (ROOT / "devices" / "roland-gx24.toml").read_text() + "\n[gpgl]\nblade_offset = [0.25]\n"
    (tmp_path / "r.toml").write_text(text)
    with pytest.raises(FoldfabError, match=r"key 'gpgl': expected no \[gpgl\] table in a hpgl profile"):
        load_device(str(tmp_path / "r.toml"))


def test_a_media_preset_sets_scoring_and_cutting_under_the_jobs_own_layers():
    device = load_device("silhouette-cameo-4")
    design = load_design(HEXAGON)
    run = lambda fab: {s.layer: (s.pen, s.force, s.speed) for s in interpret(fab.program, device).strokes}  # noqa: E731
    assert run(fabricate(design, device, replace(spec(), media="card-300"))) == \
        {"valley": (2, 20, 50), "mountain": (2, 20, 50), "cut": (1, 33, 30)}
    both = replace(spec(), media="card-300", layers={"cut": {"force": 30}})
    assert run(fabricate(design, device, both))["cut"] == (1, 30, 30)
    passes = {s.name: s.tool.passes for s in fabricate(design, device, replace(spec(), media="card-300")).plan.steps
              if isinstance(s, Pass)}
    assert passes == {"valley": 2, "mountain": 2, "cut": 2}


def test_an_unknown_media_preset_lists_the_devices_presets():
    design = load_design(HEXAGON)
    with pytest.raises(FoldfabError, match=r"hexagon-fig8a.toml: \[fabrication\] media: expected a media preset of "
                                           r"silhouette-cameo-4, got 'card-200'; its presets: copy-paper, card-160, card-300"):
        fabricate(design, load_device("silhouette-cameo-4"), replace(spec(), media="card-200"))
    with pytest.raises(FoldfabError, match=r"expected a media preset of grbl, got 'card-160'; its presets: none"):
        fabricate(design, load_device("grbl"), replace(spec(), media="card-160"))


def test_media_in_a_job_file_is_a_string():
    from foldfab.fabrication.spec import parse_fabrication

    with pytest.raises(FoldfabError, match=r"\[fabrication\]\.media: expected a string"):
        parse_fabrication({"media": 160}, "job.toml")
    assert parse_fabrication({"media": "card-160"}, "job.toml").media == "card-160"
