"""Plot plans for the program tests: a sample plan and random ones inside a device's reach, the
fabrication spec the tests use, the check that a program draws exactly its plan, and a GRBL
profile with a servo pen."""

from __future__ import annotations

import math

import numpy as np
import pytest
import vpype
from hypothesis import strategies as st

from foldfab.devices import DeviceProfile, Tool, load_device
from foldfab.fabrication.plan import Pass, Pause, PlotPlan
from foldfab.fabrication.spec import parse_fabrication
from foldfab.programs.interpret import interpret
from foldfab.programs.program import Program


def spec(**kw):
    base = {"sheet": "A3", "margin": 5, "scale": 0.4}
    base.update(kw)
    return parse_fabrication(base, "test")


def whole(job) -> dict:
    """``spec`` keys that fabricate ``job`` (a path or a design) whole: a job made to be split
    across sheets ([fabrication].split) is scaled to fit the sheet; any other is left as it is."""
    from foldfab.job import load_job

    fabrication = job.job.fabrication if hasattr(job, "job") else load_job(job).fabrication
    return {"scale": "fit"} if fabrication.get("split") else {}


def usable_rect(device: DeviceProfile, sheet=None) -> tuple[float, float, float, float]:
    """The part of the sheet the device reaches: (x0, y0, x1, y1) in sheet mm."""
    sheet = sheet or device.sheet
    x0, y0, x1, y1 = device.frame(sheet).device_rect_on_sheet(*device.plottable_area)
    return max(x0, 0), max(y0, 0), min(x1, sheet[0]), min(y1, sheet[1])


def make_document(layers: dict[int, list]) -> vpype.Document:
    doc = vpype.Document()
    for layer_id, lines in layers.items():
        doc.add(vpype.LineCollection([np.asarray(line, dtype=complex) for line in lines]), layer_id)
    return doc


def sample_plan(device: DeviceProfile, mountain_passes: int = 2) -> PlotPlan:
    """Valley, flip, mountain (repeated), cut, with a dot and a closed loop, inside the reach."""
    x0, y0, x1, y1 = usable_rect(device)
    o = complex(x0 + 5, y0 + 5)
    doc = make_document({
        1: [[o + 10, o + 60, o + 60 + 50j], [o + 20 + 20j]],
        2: [[o + 30 + 30j, o + 90 + 40j, o + 30 + 30j]],
        3: [[o, o + 100, o + 100 + 100j, o + 100j, o]],
    })
    steps = [
        Pass(1, "valley", device.tool_for("valley")),
        Pause("Flip the sheet about its left edge (mountain side up), then resume."),
        Pass(2, "mountain", device.tool_for("mountain", {"passes": mountain_passes})),
        Pass(3, "cut", device.tool_for("cut")),
    ]
    return PlotPlan(doc, steps, device.sheet)


@st.composite
def random_plans(draw, device: DeviceProfile) -> PlotPlan:
    """Random lines inside the device's reach, random layers, passes and pauses."""
    x0, y0, x1, y1 = usable_rect(device)
    xs = st.floats(x0, x1, allow_nan=False)
    ys = st.floats(y0, y1, allow_nan=False)
    point = st.builds(complex, xs, ys)
    line = st.lists(point, min_size=1, max_size=6)
    layer_ids = draw(st.lists(st.integers(1, 5), min_size=1, max_size=3, unique=True))
    layers = {lid: draw(st.lists(line, min_size=0, max_size=4)) for lid in layer_ids}
    steps = []
    for lid in layer_ids:
        name = draw(st.sampled_from(["valley", "mountain", "cut"]))
        steps.append(Pass(lid, name, device.tool_for(name, {"passes": draw(st.integers(1, 2))})))
        if draw(st.booleans()):
            steps.append(Pause(draw(st.text(min_size=0, max_size=90))))
    return PlotPlan(make_document(layers), steps, device.sheet)


def expected_strokes(plan: PlotPlan, dots: bool = True) -> list[tuple[int, int, str, int, Tool, np.ndarray]]:
    """(step, layer, name, repeat, tool, points (N, 2)) for every line the plan draws, in order
    (without one-point lines unless ``dots``: a laser burns only while it moves)."""
    out = []
    for index, step in enumerate(plan.steps):
        if isinstance(step, Pass):
            lines = [np.asarray(l) for l in plan.document.layers[step.layer_id] if len(l) > (0 if dots else 1)]
            for repeat in range(step.tool.passes):
                out.extend((index, step.layer_id, step.name, repeat, step.tool,
                            np.column_stack([l.real, l.imag])) for l in lines)
    return out


def assert_round_trip(plan: PlotPlan, device: DeviceProfile, program: Program) -> None:
    """The program draws every line of the plan on its pass, with its tool, and nothing else."""
    result = interpret(program, device, plan.sheet)
    tolerance = 0.5 / device.units_per_mm * math.sqrt(2) + 1e-9 if device.protocol != "gcode" \
        else 0.0005 * math.sqrt(2) + 1e-9
    expected = expected_strokes(plan, dots=not device.laser)
    assert result.ignored == []
    assert len(result.strokes) == len(expected)
    for stroke, (step, layer_id, name, repeat, tool, points) in zip(result.strokes, expected):
        section = stroke.section
        assert (section.step, section.layer_id, section.name, section.repeat) == \
            (step, layer_id, name, repeat)
        assert stroke.points.shape == points.shape
        assert np.hypot(*(stroke.points - points).T).max() <= tolerance
        assert stroke.speed == pytest.approx(tool.speed)
        if device.protocol in ("hpgl", "gpgl"):  # EBB and G-code strokes carry no pen number or force
            assert (stroke.pen, stroke.force) == (tool.pen, tool.force)
        else:
            assert stroke.pen_down == device.layers[name].pen_down
        assert stroke.power == (None if tool.power is None else pytest.approx(tool.power, abs=1e-6))
    plan_messages = [s.message for s in plan.steps if isinstance(s, Pause)]
    messages = [p.message for p in result.pauses]
    assert [m for m in messages if not m.startswith("Load tool")] == plan_messages
    assert [p.offset for p in result.pauses] == [p.offset for p in program.pauses]


def servo_device(folder) -> DeviceProfile:
    """The grbl profile with a servo pen: up "M3 S50", down "M3 S30" (cut "M3 S20")."""
    text = open(load_device("grbl").source).read()
    text = text.replace("pen_up = 3.0", 'pen_up = "M3 S50"').replace(
        "pen_down = -0.3", 'pen_down = "M3 S30"').replace("pen_down = -1.0", 'pen_down = "M3 S20"')
    path = folder / "servo.toml"
    path.write_text(text)
    return load_device(str(path))
