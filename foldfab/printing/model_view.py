"""The folded model drawn for the template's first page: one isometric view, faces shaded
and painted far to near (the painter's algorithm: the faces of a column origami do not
interpenetrate, and the penetration check refuses designs whose faces do)."""

from __future__ import annotations

import math

import numpy as np

from foldfab.geometry.crease_pattern import CreasePattern
from foldfab.printing.page import Shape

MAX_VIEW_FACES = 6000
"""The most polygons the view draws: a larger model is drawn on a coarser grid of its own
vertices (every few line elements and mirror planes), which a page cannot show finer anyway."""
AZIMUTH, ELEVATION = math.radians(-60.0), math.radians(30.0)
"""Where the viewer stands: in front and to the right of the model, 30 degrees above it."""
FRONT, BACK = np.array([0.96, 0.87, 0.62]), np.array([0.62, 0.76, 0.90])
"""The colours of the paper's front (the side the pattern is printed on) and back."""


def grid_ids(cp: CreasePattern) -> np.ndarray:
    """The vertex id at every (line element, plane) crossing: (J, C) from the faces."""
    j, k = cp.face_grid.T
    ids = np.zeros((j.max() + 2, k.max() + 2), np.int64)
    ids[j, k], ids[j, k + 1], ids[j + 1, k + 1], ids[j + 1, k] = cp.faces.T
    return ids


def view_faces(cp: CreasePattern) -> np.ndarray:
    """The quads (n, 4) of vertex ids the view draws: the faces, or a coarser grid of them."""
    if len(cp.faces) <= MAX_VIEW_FACES:
        return cp.faces
    ids = grid_ids(cp)
    rows, cols = ids.shape
    keep_cols = min(cols, max(2, MAX_VIEW_FACES // 30))
    keep_rows = min(rows, max(2, MAX_VIEW_FACES // keep_cols))
    js = np.unique(np.linspace(0, rows - 1, keep_rows).round().astype(int))
    ks = np.unique(np.linspace(0, cols - 1, keep_cols).round().astype(int))
    sub = ids[np.ix_(js, ks)]
    return np.stack([sub[:-1, :-1], sub[:-1, 1:], sub[1:, 1:], sub[1:, :-1]], axis=-1).reshape(-1, 4)


def model_view(cp: CreasePattern, box: tuple[float, float, float, float]) -> list[Shape]:
    """The folded model fitted into ``box`` (page mm x0, y0, x1, y1), as shaded polygons in
    drawing order."""
    faces = view_faces(cp)
    d = np.array([math.cos(ELEVATION) * math.cos(AZIMUTH), math.cos(ELEVATION) * math.sin(AZIMUTH),
                  math.sin(ELEVATION)])
    right = np.cross([0.0, 0.0, 1.0], d)
    right /= np.linalg.norm(right)
    up = np.cross(d, right)
    p = cp.vertices_3d
    screen = np.column_stack([p @ right, p @ up])
    quads = p[faces]
    normal = np.cross(quads[:, 2] - quads[:, 0], quads[:, 3] - quads[:, 1])
    length = np.linalg.norm(normal, axis=1)
    normal /= np.where(length > 0, length, 1.0)[:, None]
    facing = normal @ d
    light = d + np.array([0.3, 0.2, 0.6])
    shade = 0.45 + 0.55 * np.abs(normal @ (light / np.linalg.norm(light)))
    colors = np.where(facing[:, None] >= 0, FRONT, BACK) * shade[:, None]
    order = np.argsort((quads @ d).mean(axis=1), kind="stable")
    lo, hi = screen.min(axis=0), screen.max(axis=0)
    span = np.maximum(hi - lo, 1e-9)
    x0, y0, x1, y1 = box
    fit = min((x1 - x0) / span[0], (y1 - y0) / span[1])
    offset = np.array([(x0 + x1) / 2, (y0 + y1) / 2]) - (lo + hi) / 2 * fit
    out = []
    for f in order.tolist():
        hexed = "#" + "".join(f"{round(255 * min(c, 1.0)):02x}" for c in colors[f])
        out.append(Shape(screen[faces[f]] * fit + offset, fill=hexed, stroke=hexed, width=0.05))
    return out
