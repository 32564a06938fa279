"""Drag-knife compensation: the knife's axis path whose trailing tip cuts the drawn line."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from foldfab.devices import Blade
from foldfab.fabrication.blade import DRIFT_SHARE, centre_path, compensate, overcut, swivel_steps
from helpers.blade import assert_tip_follows, dragged_tip

RESOLUTIONS = (0.025, 0.001)   # one HP-GL unit; G-code's last decimal


@st.composite
def polylines(draw, closed: bool = False, shortest: float = 0.05):
    """A polyline (complex) of segments ``shortest`` to 30 mm long turning -179 to 179 degrees;
    ``closed``: with a segment back to its start."""
    count = draw(st.integers(2, 8))
    lengths = draw(st.lists(st.floats(shortest, 30), min_size=count, max_size=count))
    turns = draw(st.lists(st.floats(-179, 179), min_size=count, max_size=count))
    heading = draw(st.floats(-math.pi, math.pi))
    points = [complex(draw(st.floats(-50, 50)), draw(st.floats(-50, 50)))]
    for length, turn in zip(lengths, turns):
        heading += math.radians(turn)
        points.append(points[-1] + length * complex(math.cos(heading), math.sin(heading)))
    if closed:
        points.append(points[0])
    return np.array(points)


blades = st.builds(Blade, offset=st.floats(0.05, 2.0), swivel_angle=st.floats(0, 5), overcut=st.just(0.0))


@st.composite
def loops(draw):
    """A closed polygon of 3 to 8 corners round a circle of 5 to 30 mm, sides over 1.9 mm."""
    count = draw(st.integers(3, 8))
    radius = draw(st.floats(5, 30))
    angles = [2 * math.pi * (k + draw(st.floats(-0.25, 0.25))) / count for k in range(count)]
    points = radius * np.exp(1j * np.array(angles))
    return np.append(points, points[0])


@settings(max_examples=150, deadline=None)
@given(st.data(), blades, st.sampled_from(RESOLUTIONS))
def test_the_dragged_tip_follows_the_line_and_reaches_every_corner(data, blade, resolution):
    # corners at least the blade offset apart: closer ones add their swivels' drift up (DRIFT_SHARE)
    line = data.draw(polylines(shortest=blade.offset))
    (axis,) = compensate([line], blade, resolution)
    assert_tip_follows(axis, blade.offset, line, resolution)
    # each segment is one straight move of the axis, the offset ahead of it along its direction:
    # the axis traced back by the offset along its motion is the segment itself
    direction = np.diff(line) / np.abs(np.diff(line))
    for start, end in zip(line[:-1] + blade.offset * direction, line[1:] + blade.offset * direction):
        starts = np.flatnonzero(np.abs(axis[:-1] - start) < 1e-9)
        assert len(starts) and abs(axis[starts[0] + 1] - end) < 1e-9


@settings(max_examples=100, deadline=None)
@given(loops(), st.floats(0.05, 1.0), st.floats(0.1, 20), st.sampled_from(RESOLUTIONS))
def test_closed_loops_are_cut_past_their_start_by_the_overcut(loop, offset, length, resolution):
    perimeter = float(np.abs(np.diff(loop)).sum())
    length = min(length, perimeter)
    (plain,) = compensate([loop], Blade(overcut=length), resolution)
    assert np.abs(np.diff(plain)).sum() == pytest.approx(perimeter + length)
    assert np.array_equal(plain[:len(loop)], loop)
    (axis,) = compensate([loop], Blade(offset=offset, overcut=length), resolution)
    tip = assert_tip_follows(axis, offset, plain, resolution)
    assert abs(tip[-1] - plain[-1]) <= resolution   # the tip ends the overcut past the start


def test_the_overcut_goes_round_the_loop_at_most_once():
    square = np.array([0, 10, 10 + 10j, 10j, 0])
    assert np.array_equal(overcut(square, 15), [*square, 10, 10 + 5j])
    assert np.array_equal(overcut(square, 100), [*square, *square[1:]])


@settings(max_examples=50, deadline=None)
@given(st.one_of(polylines(), polylines(closed=True)), st.floats(0, 179))
def test_zero_offset_and_overcut_return_the_line_unchanged(line, swivel):
    (same,) = compensate([line], Blade(offset=0.0, swivel_angle=swivel, overcut=0.0), 0.025)
    assert np.array_equal(same, line)


def test_open_lines_get_no_overcut():
    line = np.array([0, 10, 10 + 10j])
    (same,) = compensate([line], Blade(overcut=2.0), 0.025)
    assert np.array_equal(same, line)


@pytest.mark.parametrize("turn", [10.0, 90.0, 135.0, 180.0])
def test_corners_sharper_than_the_swivel_angle_get_an_arc_round_the_corner(turn):
    offset, resolution = 0.5, 0.025
    heading = complex(math.cos(math.radians(turn)), math.sin(math.radians(turn)))
    line = np.array([-10, 0, 10 * heading])
    axis = centre_path(line, offset, 5.0, resolution)
    arc = axis[1:-1]
    assert np.allclose(np.abs(arc), offset)                       # centred on the corner
    assert arc[0] == pytest.approx(offset) and arc[-1] == pytest.approx(offset * heading)
    assert len(arc) - 1 == swivel_steps(offset, math.radians(turn), resolution) >= (turn > 45) + 1
    sagitta = offset * (1 - np.cos(np.angle(arc[1:] / arc[:-1]) / 2))
    assert sagitta.max() <= resolution / DRIFT_SHARE
    # a gentler corner is joined by one straight move
    gentle = centre_path(line, offset, turn + 1, resolution)
    assert len(gentle) == 4 and np.allclose(np.abs(gentle[1:3]), offset)


def test_swivel_steps_keep_the_tip_on_the_corner():
    # the drift the steps are chosen by, measured on the model drag knife: half a resolution
    for offset in (0.1, 0.25, 1.0):
        for resolution in RESOLUTIONS:
            for turn in np.radians([6, 10, 20, 60, 90, 150, 179.9]):
                steps = swivel_steps(offset, turn, resolution)
                arc = offset * np.exp(1j * turn * np.arange(steps + 1) / steps)
                axis = np.concatenate([[-1 + offset], arc])         # arrive along +x at the corner 0
                tip = dragged_tip(axis, offset, samples=8)
                assert np.abs(tip[8:]).max() <= resolution / DRIFT_SHARE   # from the arrival on


def test_without_compensation_the_tip_cuts_the_corner():
    # the reason for all this: the tip dragged along the line itself rounds the corner off
    line = np.array([0, 10, 10 + 10j])
    tip = dragged_tip(line, 0.5)
    assert np.abs(tip - 10).min() > 0.1
