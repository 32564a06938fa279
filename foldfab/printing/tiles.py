"""Tiling a crease pattern across pages: which part of the pattern each page shows.

Every page keeps a header band and a footer band for its labels; the tile area between them
shows the pattern at its printed size.  Neighbouring tiles share ``overlap`` mm of pattern
so that the pages can be trimmed at the crop marks and taped with the alignment marks on top
of one another.  Rows count from the top of the pattern, columns from its left.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from foldfab.errors import FoldfabError

HEADER = 10.0
"""mm: the band above the tile area (design name, page number)."""
FOOTER = 26.0
"""mm: the band below it (legend, scale bar, tile map)."""
MAX_PAGES = 1000
"""The most pages a template may have."""


@dataclass(frozen=True)
class Tiling:
    """The pages of one crease pattern: pattern points ``p`` (in mm of the crease pattern) are
    printed at ``scale``; tile (r, c) shows the printed pattern's window
    ``[origin_x + c * step_x, ... + area width] x [origin_y - r * step_y - area height, origin_y - r * step_y]``."""

    paper: tuple[float, float]
    area: tuple[float, float, float, float]   # page mm: x0, y0, x1, y1
    origin: tuple[float, float]               # printed mm: top-left of tile (0, 0)
    step: tuple[float, float]
    rows: int
    cols: int
    scale: float

    @property
    def count(self) -> int:
        return self.rows * self.cols

    def to_page(self, points: np.ndarray, row: int, col: int) -> np.ndarray:
        """Crease-pattern points (n, 2) where they are printed on tile (row, col)."""
        x0, y0, x1, y1 = self.area
        left = self.origin[0] + col * self.step[0]
        top = self.origin[1] - row * self.step[1]
        return points * self.scale - np.array([left, top]) + np.array([x0, y1])

    def window(self, row: int, col: int) -> tuple[float, float, float, float]:
        """The crease-pattern rectangle (x0, y0, x1, y1, unscaled mm) tile (row, col) shows."""
        x0, y0, x1, y1 = self.area
        left = self.origin[0] + col * self.step[0]
        top = self.origin[1] - row * self.step[1]
        s = self.scale
        return left / s, (top - (y1 - y0)) / s, (left + x1 - x0) / s, top / s


def _count(length: float, area: float, overlap: float) -> int:
    return max(1, math.ceil((length - overlap) / (area - overlap) - 1e-9))


def tile(bounds: tuple[float, float, float, float], paper: tuple[float, float], margin: float, overlap: float,
         scale: float) -> Tiling:
    """Tile the crease pattern spanning ``bounds`` (x0, y0, x1, y1, mm) at ``scale`` across
    pages of ``paper``; the pattern is centred in the tiles' span."""
    pw, ph = paper
    area = (margin, margin + FOOTER, pw - margin, ph - margin - HEADER)
    aw, ah = area[2] - area[0], area[3] - area[1]
    overlap = min(overlap, aw / 3, ah / 3)
    width, height = (bounds[2] - bounds[0]) * scale, (bounds[3] - bounds[1]) * scale
    cols, rows = _count(width, aw, overlap), _count(height, ah, overlap)
    step = (aw - overlap, ah - overlap)
    span = (cols * step[0] + overlap, rows * step[1] + overlap)
    origin = (bounds[0] * scale - (span[0] - width) / 2, bounds[3] * scale + (span[1] - height) / 2)
    return Tiling(paper, area, origin, step, rows, cols, scale)


def tile_patterns(bounds: list[tuple[float, float, float, float]], paper: tuple[float, float], turnable: bool,
                  margin: float, overlap: float, scale: float, paper_name: str) -> list[Tiling]:
    """The tilings of several crease patterns on one paper orientation: as given, or, when
    ``turnable``, turned too if that needs fewer pages (portrait on a tie)."""
    choices = [paper] + ([(paper[1], paper[0])] if turnable and paper[0] != paper[1] else [])
    best = min(([tile(b, p, margin, overlap, scale) for b in bounds] for p in choices),
               key=lambda tilings: sum(t.count for t in tilings))
    pages = sum(t.count for t in best)
    if pages > MAX_PAGES:
        raise FoldfabError(f"the pattern at scale {scale:g} needs {pages:,} pages of {paper_name}, more than "
                           f"{MAX_PAGES:,}; print it at a smaller --scale or on larger --paper")
    return best
