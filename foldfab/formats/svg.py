"""SVG crease pattern in Origami Simulator's conventions.

Flat ``<line>`` elements only (no groups, transforms or CSS); stroke colour by
assignment and ``stroke-opacity`` = |fold angle| / 180.  The sheet is drawn as
seen from its front: crease-pattern y (up) becomes SVG y (down) by a flip, so
mountains stay mountains on screen.

Origami Simulator's import merges vertices closer than 3 of the SVG's user units
(its default tolerance), so the coordinates are written in a user unit fine enough
that the import is exact (:func:`user_unit`); ``width`` and ``height`` in mm keep the
sheet's physical size.

A split piece's match marks (its number, its tabs' and edges' letters) go on a layer of their
own, an Inkscape layer group ``marks`` in the cut's colour, as on the plotter's marks layer.
Origami Simulator imports only the root element's own ``line``, ``path``, ``polyline``, ...
children (``loadSVG`` in its ``js/pattern.js``), so it never reads the marks as creases.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from foldfab.geometry.crease_pattern import CreasePattern

COLORS = {"M": "#ff0000", "V": "#0000ff", "B": "#000000", "F": "#ffff00"}
IMPORT_TOLERANCE = 3.0
"""User units: Origami Simulator merges vertices closer than this by default."""
CLEARANCE = 10.0
"""User units the closest two vertices are at least apart: the import's tolerance with a margin."""
COARSEST_UNIT = 0.1
"""mm: the user unit of a design whose vertices are at least 1 mm apart."""
INKSCAPE = "http://www.inkscape.org/namespaces/inkscape"
MARKS_COLOR = COLORS["B"]
"""The match marks' colour: the cut's, as the plotter draws them (never cut)."""


def user_unit(vertices: np.ndarray) -> float:
    """mm per SVG user unit: 0.1, or the largest power of ten below it that puts the closest
    two distinct vertices at least :data:`CLEARANCE` units apart.  A unit per design (rather
    than one fixed fine unit) keeps ordinary patterns at a readable 0.1 mm and still imports
    a pattern with sub-millimetre details exactly."""
    shortest = _shortest_distance(vertices, CLEARANCE * COARSEST_UNIT)
    if shortest is None:
        return COARSEST_UNIT
    return 10.0 ** math.floor(math.log10(shortest / CLEARANCE))


def _shortest_distance(vertices: np.ndarray, reach: float) -> float | None:
    """The distance between the closest two distinct vertices, if it is under ``reach`` (None:
    no two are that close).  Boxes of side ``reach`` round the vertices overlap for every such
    pair, so the penetration check's uniform grid (:func:`foldfab.geometry.penetration.candidate_pairs`) finds
    them all, in numpy alone (no spatial index to load for writing an SVG)."""
    from foldfab.geometry.penetration import candidate_pairs

    unique = np.unique(vertices, axis=0)
    if len(unique) < 2:
        return None
    boxes = np.column_stack([unique, np.zeros(len(unique))])  # the grid is 3D; the sheet lies at z = 0
    pairs = candidate_pairs(boxes - reach / 2, boxes + reach / 2)
    if not len(pairs):
        return None
    shortest = float(np.hypot(*(unique[pairs[:, 0]] - unique[pairs[:, 1]]).T).min())
    return shortest if shortest < reach else None


def dumps(cp: CreasePattern, stroke_width: float = 0.2, marks: Sequence[np.ndarray] = ()) -> str:
    """SVG text of ``cp``, and of a split piece's ``marks`` (strokes (N, 2) in crease-pattern mm)
    on their own ``marks`` layer; ``stroke_width`` in mm."""
    unit = user_unit(cp.vertices)
    lo = cp.vertices.min(axis=0)
    hi = cp.vertices.max(axis=0)
    width, height = hi - lo
    p = cp.vertices[cp.edges]
    x = (p[..., 0] - lo[0]) / unit
    y = (hi[1] - p[..., 1]) / unit
    opacity = np.where(cp.assignment == "B", 1.0, np.abs(cp.fold_angle) / 180.0)
    # Borders last so the outline is drawn on top.
    order = np.argsort(cp.assignment == "B", kind="stable")
    lines = [
        f'<line x1="{x[i, 0]:.6f}" y1="{y[i, 0]:.6f}" x2="{x[i, 1]:.6f}" y2="{y[i, 1]:.6f}" '
        f'stroke="{COLORS[cp.assignment[i]]}" stroke-opacity="{opacity[i]:.6f}" '
        f'stroke-width="{stroke_width / unit:g}"/>'
        for i in order.tolist()
    ]
    layer = ""
    if len(marks):
        polylines = "\n".join(
            '<polyline points="' + " ".join(f"{(px - lo[0]) / unit:.6f},{(hi[1] - py) / unit:.6f}"
                                            for px, py in stroke.tolist()) + '"/>' for stroke in marks)
        layer = (f'\n<g id="marks" inkscape:groupmode="layer" inkscape:label="marks" fill="none" '
                 f'stroke="{MARKS_COLOR}" stroke-width="{stroke_width / unit:g}">\n{polylines}\n</g>')
    namespace = f' xmlns:inkscape="{INKSCAPE}"' if layer else ""
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n'
            f'<svg xmlns="http://www.w3.org/2000/svg"{namespace} version="1.1" width="{width:.6f}mm" '
            f'height="{height:.6f}mm" viewBox="0 0 {width / unit:.6f} {height / unit:.6f}">\n'
            + "\n".join(lines) + layer + "\n</svg>\n")
