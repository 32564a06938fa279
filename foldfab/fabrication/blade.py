"""Drag-knife compensation: the path a knife's axis takes so that its trailing tip cuts the line.

A drag knife's tip trails its axis by the blade offset ``r``, in the direction of travel, and
swivels freely: along a straight move the tip runs ``r`` behind the axis, and when the axis
circles the tip at radius ``r`` the blade turns in place.  So, as Inkcut's blade-offset filter
and cutter firmware do it (docs/design.md), the axis leads each drawn segment by ``r`` along it,
and at every corner turning more than the swivel angle it swings round the corner on an arc of
radius ``r`` centred on the corner, from the old direction to the new one.  ``overcut`` runs a
closed loop on past its start, so the last cut crosses the first and the piece comes free.

Polylines are complex arrays, sheet millimetres; pure numpy.
"""

from __future__ import annotations

import math

import numpy as np

from foldfab.devices import Blade
from foldfab.fabrication.optimize import _closed  # the loops the optimizer may start anywhere

SAME_POINT = 1e-9
"""mm: points closer than this are one point (a zero-length segment has no direction)."""


def compensate(lines, blade: Blade, resolution: float) -> list[np.ndarray]:
    """The knife-axis paths of polylines ``lines`` (each overcut if closed within ``resolution``,
    then offset): see
    :func:`overcut` and :func:`centre_path`.  A zero offset and overcut return ``lines`` as they are."""
    out = []
    for line in lines:
        line = np.asarray(line, dtype=complex)
        if blade.overcut > 0 and _closed(line, resolution):
            line = overcut(line, blade.overcut)
        if blade.offset > 0:
            line = centre_path(line, blade.offset, blade.swivel_angle, resolution)
        out.append(line)
    return out


def blade_text(layer: str, blade: Blade) -> str:
    """How a layer's lines are compensated, as the report and the preview say it."""
    return (f"{layer}: drag knife compensated for a {blade.offset:g} mm blade offset, swivels at corners over "
            f"{blade.swivel_angle:g} degrees, {blade.overcut:g} mm overcut")


def overcut(loop: np.ndarray, length: float) -> np.ndarray:
    """Closed ``loop`` continued along itself ``length`` mm past its start (at most once round:
    a longer overcut only cuts the same line again)."""
    length = min(length, float(np.abs(np.diff(loop)).sum()))
    extra, done = [], 0.0
    for a, b in zip(loop[:-1], loop[1:]):
        step = abs(b - a)
        if done + step >= length:
            if step > 0:
                extra.append(a + (b - a) * (length - done) / step)
            break
        extra.append(b)
        done += step
    return np.concatenate([loop, extra])


def centre_path(line: np.ndarray, offset: float, swivel_angle: float, resolution: float) -> np.ndarray:
    """The axis path that drags the tip along ``line``: each segment moved ``offset`` mm along
    its own direction, joined at each corner turning more than ``swivel_angle`` degrees by an
    arc of radius ``offset`` round the corner (:func:`swivel_steps` chords), otherwise by a
    straight move.  The tip starts with the blade along the first segment."""
    points = _distinct(np.asarray(line, dtype=complex))
    if len(points) < 2:
        return np.asarray(line, dtype=complex)
    directions = np.diff(points)
    directions = directions / np.abs(directions)
    limit = math.radians(swivel_angle)
    path = [points[0] + offset * directions[0]]
    for corner, before, after in zip(points[1:-1], directions[:-1], directions[1:]):
        path.append(corner + offset * before)
        turn = float(np.angle(after / before))
        if abs(turn) > limit:
            steps = swivel_steps(offset, turn, resolution)
            path.extend(corner + offset * before * np.exp(1j * turn * np.arange(1, steps) / steps))
        path.append(corner + offset * after)
    path.append(points[-1] + offset * directions[-1])
    return _distinct(np.array(path))


DRIFT_SHARE = 4
"""A swivel arc may move the tip by at most the resolution over this: the drift of swivels at
corners closer together than the blade offset adds up before straight moves take it out."""


def swivel_steps(offset: float, turn: float, resolution: float) -> int:
    """Chords of a swivel arc of radius ``offset`` turning ``turn`` radians, so that the knife
    strays from the arc, and its tip from the corner, by at most ``resolution / DRIFT_SHARE``.

    Each chord cuts inside the arc by its sagitta ``offset * (1 - cos(step / 2))``, and on it
    the axis comes nearer the corner and pushes the dragged tip back by about as much; over
    the arc the tip's drift adds up to about ``offset * |turn| * step**2 / 12``.  Both are
    bounded by ``offset * step**2 * (1 + |turn|) / 8`` (measured on the drag-knife model of
    the tests: tests/fabrication/test_blade.py)."""
    tolerance = resolution / DRIFT_SHARE
    sweep = abs(turn)
    by_chord = 2 * math.acos(max(1 - tolerance / offset, 0.0))
    by_drift = math.sqrt(8 * tolerance / (offset * (1 + sweep)))
    return max(1, math.ceil(sweep / min(by_chord, by_drift, math.pi / 2)))


def _distinct(points: np.ndarray) -> np.ndarray:
    """``points`` without those at the same place as the point before them."""
    if len(points) < 2:
        return points
    keep = np.concatenate([[True], np.abs(np.diff(points)) > SAME_POINT])
    return points[keep]
