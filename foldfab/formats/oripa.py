"""ORIPA ``.cp``: one segment per line, ``type x0 y0 x1 y1`` (1 border, 2 mountain, 3 valley).

ORIPA has no flat type; flat creases are left out (they are never folded).
"""

from __future__ import annotations

from foldfab.geometry.crease_pattern import CreasePattern

TYPES = {"B": 1, "M": 2, "V": 3}


def dumps(cp: CreasePattern) -> str:
    """ORIPA text of ``cp``."""
    p = cp.vertices[cp.edges]
    rows = []
    for i, kind in enumerate(cp.assignment.tolist()):
        if kind in TYPES:
            (x0, y0), (x1, y1) = p[i]
            rows.append(f"{TYPES[kind]} {x0:.9f} {y0:.9f} {x1:.9f} {y1:.9f}")
    return "\n".join(rows) + "\n"
