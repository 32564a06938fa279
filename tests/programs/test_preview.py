"""Dry-run SVG preview of an interpreted program."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from foldfab.devices import load_device
from foldfab.programs.estimate import estimate
from foldfab.programs.interpret import interpret
from foldfab.programs.preview import COLORS, render_preview
from foldfab.programs.languages import write_program
from helpers.plans import sample_plan

SVG = "{http://www.w3.org/2000/svg}"


def preview(name: str):
    device = load_device(name)
    plan = sample_plan(device)
    result = interpret(write_program(plan, device), device, plan.sheet)
    return device, plan, result, render_preview(result, device, plan)


@pytest.mark.parametrize("name", ["hp7475a", "grbl"])
def test_preview_shows_strokes_per_layer_travel_and_pauses(name):
    device, plan, result, svg = preview(name)
    root = ET.fromstring(svg)
    width, height = plan.sheet
    assert root.get("width").endswith("mm") and root.get("height").endswith("mm")
    assert [float(v) for v in root.get("viewBox").split()][2] == pytest.approx(width + 20)
    sheet = root.find(f"{SVG}rect[@id='sheet']")
    assert (float(sheet.get("width")), float(sheet.get("height"))) == (width, height)
    area = root.find(f"{SVG}rect[@id='plottable-area']")
    x0, y0, x1, y1 = device.frame(plan.sheet).device_rect_on_sheet(*device.plottable_area)
    assert (float(area.get("x")), float(area.get("width"))) == pytest.approx((x0, x1 - x0))

    groups = {g.get("data-layer"): g for g in root.iter(f"{SVG}g") if g.get("data-layer")}
    assert list(groups) == ["valley", "mountain", "cut"]
    for name_, group in groups.items():
        assert group.get("stroke") == COLORS[name_]
        strokes = [s for s in result.strokes if s.layer == name_]
        drawn = list(group)
        assert len(drawn) == len(strokes)
        for stroke, element in zip(strokes, drawn):
            if element.tag == f"{SVG}polyline":
                points = [[float(v) for v in p.split(",")] for p in element.get("points").split()]
                assert np.allclose(points, stroke.points, atol=1e-3)
            else:  # a dot
                assert element.tag == f"{SVG}circle" and len(stroke.points) == 1

    travel = root.find(f"{SVG}path[@id='travel']")
    assert travel.get("stroke-dasharray") and float(travel.get("stroke-width")) < 0.3
    assert travel.get("d").count("M") == len(result.travels)

    legend = " ".join(t.text for t in root.find(f"{SVG}g[@id='legend']").iter(f"{SVG}text"))
    times = estimate(result, device)
    for layer, stats in times.layers.items():
        assert f"{layer}: {stats.drawn_length:.0f} mm drawn, {stats.pen_lifts} pen lift" in legend
        assert f"{stats.travel_length:.0f} mm travel" in legend
    assert re.search(r"total: [\d.]+ s \(lower bound [\d.]+ s\)", legend)
    assert "pause 1: Flip the sheet about its left edge" in legend
    assert len(root.findall(f"{SVG}g[@class='pause']")) == len(result.pauses) == 1


def test_preview_is_deterministic_and_accepts_a_sheet_size():
    device, plan, result, svg = preview("roland-gx24")
    assert svg == render_preview(result, device, plan.sheet)
    assert svg == preview("roland-gx24")[3]


def test_other_layers_are_grey_and_unlabelled_programs_still_render():
    device = load_device("hp7475a")
    text = write_program(sample_plan(device), device).text  # bare text: no sections
    result = interpret(text, device)
    svg = render_preview(result, device, device.sheet)
    root = ET.fromstring(svg)
    layers = [g.get("data-layer") for g in root.iter(f"{SVG}g") if g.get("data-layer")]
    assert layers == ["pen 1", "pen 2", "pen 3"]
    assert all(g.get("stroke") == "#808080" for g in root.iter(f"{SVG}g") if g.get("data-layer"))
