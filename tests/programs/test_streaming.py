"""Programs streamed to their file as the writer makes them: the same bytes as the whole text,
the same record, and ``foldfab export`` leaves nothing behind when it fails midway."""

from __future__ import annotations

import gc
import json
import weakref

import numpy as np
import pytest
from hypothesis import given, settings

from foldfab.design import load_design
from foldfab.devices import load_device
from foldfab.errors import FoldfabError
from foldfab.fabricate import fabricate
from foldfab.programs.languages import write_program
from helpers import HEXAGON, JOBS
from helpers.cli import run
from helpers.plans import make_document, random_plans, usable_rect
from foldfab.fabrication.plan import Pass, Pause, PlotPlan

PROFILES = ["graphtec-ce6000", "hp7475a", "grbl", "grbl-laser", "axidraw-v3", "silhouette-cameo-4"]
"""One or more shipped profiles of each language (HP-GL, G-code with a pen and a laser, EBB, GP-GL)."""


def streamed(plan, device):
    """The program written through a sink, and the blocks the sink received."""
    blocks: list[bytes] = []
    return write_program(plan, device, blocks.append), blocks


def assert_same_program(whole, stream, blocks) -> None:
    assert stream.text is None and all(isinstance(b, bytes) for b in blocks)
    assert b"".join(blocks) == whole.text.encode("ascii")
    assert stream.size == whole.size == len(whole.text)
    assert (stream.sections, stream.pauses, stream.protocol, stream.device) == \
        (whole.sections, whole.pauses, whole.protocol, whole.device)
    assert (stream.recording is None) == (whole.recording is None)
    if whole.recording is not None:
        for key in ("sizes", "speeds", "layers", "travels", "leads_to", "byte_ends"):
            assert getattr(stream.recording, key) == getattr(whole.recording, key), key
        assert len(stream.recording.chunks) == len(whole.recording.chunks)
        assert all(np.array_equal(a, b) for a, b in zip(stream.recording.chunks, whole.recording.chunks))


@pytest.mark.parametrize("name", PROFILES)
def test_a_streamed_random_plan_is_the_whole_text_byte_for_byte(name):
    device = load_device(name)

    @settings(max_examples=25, deadline=None)
    @given(random_plans(device))
    def check(plan):
        assert_same_program(write_program(plan, device), *streamed(plan, device))

    check()


def many_lines(device, count: int) -> PlotPlan:
    """``count`` short lines over the device's reach, a pause between two layers: thousands of writes."""
    x0, y0, x1, y1 = usable_rect(device)
    rng = np.random.default_rng(count)
    starts = rng.uniform([x0, y0], [x1 - 2, y1 - 2], (count, 2))
    lines = [[complex(*p), complex(*(p + 1.5)), complex(p[0], p[1] + 1)] for p in starts]
    doc = make_document({1: lines[: count // 2], 2: lines[count // 2:]})
    steps = [Pass(1, "valley", device.tool_for("valley")), Pause("Flip the sheet"), Pass(2, "cut", device.tool_for("cut"))]
    return PlotPlan(doc, steps, device.sheet)


@pytest.mark.parametrize("name", PROFILES)
def test_a_large_program_streams_in_many_blocks_and_the_same_bytes(name):
    device = load_device(name)
    plan = many_lines(device, 600 if device.protocol == "ebb" else 20000)   # HP-GL: several batches
    stream, blocks = streamed(plan, device)
    assert len(blocks) > 2 and max(map(len, blocks)) < stream.size / 2   # never the whole text at once
    assert_same_program(write_program(plan, device), stream, blocks)


@pytest.mark.parametrize("device_name, suffix", [("graphtec-ce6000", ".plt"), ("grbl", ".gcode"),
                                                 ("silhouette-cameo-4", ".gpgl"), ("axidraw-v3", ".ebb")])
@pytest.mark.parametrize("job", JOBS[:3], ids=[j.stem for j in JOBS[:3]])
def test_export_writes_what_the_writer_makes_whole_and_reports_its_size(job, device_name, suffix, tmp_path, capsys):
    device = load_device(device_name)
    out = tmp_path / f"program{suffix}"
    rc, text, err = run(capsys, "export", job, "--device", device_name, "-o", out, "--json", "--scale", "fit")
    assert rc == 0, err
    report = json.loads(text)
    sheets = report.get("sheets", [report])
    for info in sheets:
        assert info["program_bytes"] == len(open(info["written"], "rb").read())
    if len(sheets) == 1:
        from foldfab.fabrication.spec import job_spec

        design = load_design(job)
        from dataclasses import replace

        fab = fabricate(design, device, replace(job_spec(design.job), scale="fit"))
        assert out.read_bytes() == fab.program.text.encode("ascii")
    rc, text, err = run(capsys, "export", job, "--device", device_name, "-o", tmp_path / f"again{suffix}",
                        "--json", "--scale", "fit", "--verify")
    assert rc == 0 and json.loads(text) == json.loads(json.dumps(report).replace(str(out), str(tmp_path / f"again{suffix}"))
                                                      .replace("program-", "again-")), err
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []


@pytest.mark.parametrize("error, code", [(FoldfabError, 2), (KeyboardInterrupt, 130), (OSError, 2)])
def test_an_export_failing_midway_leaves_no_program_and_no_temporary_file(error, code, tmp_path, monkeypatch,
                                                                           capsys):
    from foldfab.programs import languages

    writer = languages.WRITERS["hpgl"]

    def failing(plan, device, sink=None):
        def half(data: bytes):
            sink(data[: len(data) // 2])   # bytes reach the temporary file first
            raise error("the writer failed midway")
        return writer(plan, device, half)

    monkeypatch.setitem(languages.WRITERS, "hpgl", failing)
    out = tmp_path / "hexagon.plt"
    assert run(capsys, "export", HEXAGON, "--device", "graphtec-ce6000", "-o", out)[0] == code
    assert list(tmp_path.iterdir()) == []
    out.write_bytes(b"the old program")
    assert run(capsys, "export", HEXAGON, "--device", "graphtec-ce6000", "-o", out)[0] == code
    assert [p.name for p in tmp_path.iterdir()] == ["hexagon.plt"] and out.read_bytes() == b"the old program"


def test_export_lets_the_design_go_before_it_optimizes_and_writes(tmp_path, monkeypatch, capsys):
    """The design's crease pattern and mesh (a large design's biggest part) are gone while the
    layout is optimized and the program written: only the laid-out layers stay."""
    import foldfab.design
    import foldfab.fabricate

    built, alive = [], []
    build, finish = foldfab.design.build_design, foldfab.fabricate.finish_plan

    def remembered(*args, **kwargs):
        design = build(*args, **kwargs)
        built.append(weakref.ref(design))
        return design

    def finishing(*args, **kwargs):
        gc.collect()
        alive.append(built[-1]() is not None)
        return finish(*args, **kwargs)

    monkeypatch.setattr(foldfab.design, "build_design", remembered)
    monkeypatch.setattr(foldfab.fabricate, "finish_plan", finishing)
    rc, _, err = run(capsys, "export", HEXAGON, "--device", "graphtec-ce6000", "-o", tmp_path / "h.plt")
    assert rc == 0, err
    assert alive and not any(alive)   # the optimization, and the unoptimized plan for travel_before


def test_a_fabrication_without_its_layout_keeps_its_travel_before():
    device = load_device("graphtec-ce6000")
    fab = fabricate(load_design(HEXAGON), device)
    lighter = fab.without_layout()
    assert lighter.layout is None and lighter.plan is fab.plan and lighter.program is fab.program
    assert lighter.travel_before == fab.travel_before and lighter.travel_after == fab.travel_after
    assert fab.travel_before["total"] > fab.travel_after["total"]


def test_a_program_s_size_is_its_text_s_length_or_the_streamed_bytes():
    from dataclasses import replace

    device = load_device("graphtec-ce6000")
    plan = many_lines(device, 50)
    whole, (stream, blocks) = write_program(plan, device), streamed(plan, device)
    assert stream.size == sum(map(len, blocks)) == whole.size
    assert replace(whole, text="IN;").size == 3 and replace(stream, text="IN;PU0,0;").size == 9
