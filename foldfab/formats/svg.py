"""SVG crease pattern in Origami Simulator's conventions, in millimetres.

Flat ``<line>`` elements only (no groups, transforms or CSS); stroke colour by
assignment and ``stroke-opacity`` = |fold angle| / 180.  The sheet is drawn as
seen from its front: crease-pattern y (up) becomes SVG y (down) by a flip, so
mountains stay mountains on screen.
"""

from __future__ import annotations

import numpy as np

from foldfab.crease_pattern import CreasePattern

COLORS = {"M": "#ff0000", "V": "#0000ff", "B": "#000000", "F": "#ffff00"}


def dumps(cp: CreasePattern, stroke_width: float = 0.2) -> str:
    """SVG text of ``cp``."""
    lo = cp.vertices.min(axis=0)
    hi = cp.vertices.max(axis=0)
    width, height = hi - lo
    p = cp.vertices[cp.edges]
    x = p[..., 0] - lo[0]
    y = hi[1] - p[..., 1]
    opacity = np.where(cp.assignment == "B", 1.0, np.abs(cp.fold_angle) / 180.0)
    # Borders last so the outline is drawn on top.
    order = np.argsort(cp.assignment == "B", kind="stable")
    lines = [
        f'<line x1="{x[i, 0]:.6f}" y1="{y[i, 0]:.6f}" x2="{x[i, 1]:.6f}" y2="{y[i, 1]:.6f}" '
        f'stroke="{COLORS[cp.assignment[i]]}" stroke-opacity="{opacity[i]:.6f}" stroke-width="{stroke_width:g}"/>'
        for i in order.tolist()
    ]
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n'
            f'<svg xmlns="http://www.w3.org/2000/svg" version="1.1" width="{width:.6f}mm" height="{height:.6f}mm" '
            f'viewBox="0 0 {width:.6f} {height:.6f}">\n' + "\n".join(lines) + "\n</svg>\n")
