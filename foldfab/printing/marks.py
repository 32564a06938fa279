"""What every page of a template carries besides the pattern: crop and alignment marks at the
tile overlaps, the 50 mm scale bar, the legend and the map of tiles."""

from __future__ import annotations

import numpy as np

from foldfab.printing.page import Lines, Shape, Text, rect
from foldfab.printing.styles import LineStyle
from foldfab.printing.tiles import Tiling

MARK = "#000000"
MARK_WIDTH = 0.15
CROP = 5.0
"""mm: the length of a crop mark, drawn outside the tile area along its edges."""
SCALE_BAR = 50.0
"""mm: the length of the scale bar, printed on every page."""
SCALE_BAR_HEIGHT = 1.5
TARGET = 2.0
"""mm: the radius of an alignment target."""


def crop_marks(tiling: Tiling) -> Lines:
    """Corner crop marks just outside the tile area, and ticks where the overlap with a
    neighbouring tile begins and ends: every page alike, since every tile has the same area."""
    x0, y0, x1, y1 = tiling.area
    gap = 1.0
    lines = []
    for x in (x0, x1):
        lines += [np.array([[x, y1 + gap], [x, y1 + gap + CROP]]), np.array([[x, y0 - gap], [x, y0 - gap - CROP]])]
    for y in (y0, y1):
        lines += [np.array([[x0 - gap, y], [x0 - gap - CROP, y]]), np.array([[x1 + gap, y], [x1 + gap + CROP, y]])]
    overlap = tiling.area[2] - tiling.area[0] - tiling.step[0]
    if overlap > 0 and tiling.cols > 1:
        for x in (x0 + overlap, x1 - overlap):
            lines += [np.array([[x, y1 + gap], [x, y1 + gap + CROP / 2]]), np.array([[x, y0 - gap], [x, y0 - gap - CROP / 2]])]
    if overlap > 0 and tiling.rows > 1:
        for y in (y0 + overlap, y1 - overlap):
            lines += [np.array([[x0 - gap, y], [x0 - gap - CROP / 2, y]]), np.array([[x1 + gap, y], [x1 + gap + CROP / 2, y]])]
    return Lines(lines, MARK, MARK_WIDTH)


def _target(x: float, y: float) -> list[np.ndarray]:
    angle = np.linspace(0.0, 2 * np.pi, 33)
    circle = np.column_stack([x + TARGET * np.cos(angle), y + TARGET * np.sin(angle)])
    r = TARGET * 1.6
    return [circle, np.array([[x - r, y], [x + r, y]]), np.array([[x, y - r], [x, y + r]])]


def alignment_marks(tiling: Tiling, row: int, col: int) -> Lines:
    """Targets in the middle of every overlap this tile shares with a neighbour, placed at the
    same point of the pattern on both tiles so that taped pages line up."""
    x0, y0, x1, y1 = tiling.area
    left = tiling.origin[0] + col * tiling.step[0]
    top = tiling.origin[1] - row * tiling.step[1]
    overlap_x = x1 - x0 - tiling.step[0]
    overlap_y = y1 - y0 - tiling.step[1]
    points = []  # printed-pattern mm
    for c in (col, col + 1):  # the seams at this tile's left (c = col) and right (c = col + 1)
        if 0 < c < tiling.cols and overlap_x > 0:
            seam = tiling.origin[0] + c * tiling.step[0] + overlap_x / 2
            points += [(seam, top - f * (y1 - y0)) for f in (0.25, 0.75)]
    for r in (row, row + 1):
        if 0 < r < tiling.rows and overlap_y > 0:
            seam = tiling.origin[1] - r * tiling.step[1] - overlap_y / 2
            points += [(left + f * (x1 - x0), seam) for f in (0.25, 0.75)]
    lines = []
    for px, py in points:
        lines += _target(px - left + x0, py - top + y1)
    return Lines(lines, MARK, MARK_WIDTH, clip=tiling.area)


def scale_bar(x: float, y: float) -> list[Shape | Text]:
    """A solid bar exactly :data:`SCALE_BAR` mm long from (x, y), and its caption."""
    return [Shape(rect(x, y, x + SCALE_BAR, y + SCALE_BAR_HEIGHT), fill=MARK),
            Text(x + SCALE_BAR + 3, y, f"{SCALE_BAR:g} mm: measure this bar; print at 100 %, not 'fit to page'",
                 size=6.5)]


def legend(x: float, y: float, styles: dict[str, LineStyle], width: float) -> list[Lines | Text]:
    """A sample of every line style with its name, in a row from (x, y)."""
    items: list[Lines | Text] = []
    entry = width / max(len(styles), 1)
    for i, style in enumerate(styles.values()):
        sx = x + i * entry
        items.append(Lines([np.array([[sx, y + 1.0], [sx + 12.0, y + 1.0]])], style.color, style.width, style.dash))
        items.append(Text(sx + 14.0, y, style.label, size=6.5))
    return items


def tile_map(tiling: Tiling, row: int | None, col: int | None, box: tuple[float, float, float, float]) -> list[Shape]:
    """The rows and columns of tiles as a small grid in ``box``, tile (row, col) filled."""
    x0, y0, x1, y1 = box
    cell = min((x1 - x0) / tiling.cols, (y1 - y0) / tiling.rows, 6.0)
    top = y1
    shapes = []
    for r in range(tiling.rows):
        for c in range(tiling.cols):
            here = r == row and c == col
            shapes.append(Shape(rect(x0 + c * cell, top - (r + 1) * cell, x0 + (c + 1) * cell, top - r * cell),
                                fill="#404040" if here else None, stroke=MARK, width=0.1))
    return shapes
