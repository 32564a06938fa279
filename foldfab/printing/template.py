"""A printable template's pages: a first page with the folded model, folding notes and the
map of pages, then the crease pattern at its printed size, tiled page after page.

:func:`lay_out` takes a list of crease patterns, each printed on its own group of pages: the
whole design, or the pieces of a design split across sheets
(:func:`~foldfab.fabrication.pieces.design_pieces`, the pieces the plotter's programs draw),
each with its match marks and the letters of the tabs and edges it is glued by.
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from foldfab.geometry.crease_pattern import CreasePattern
from foldfab.geometry.split import Join, Piece
from foldfab.printing.creases import arc_lengths, crease_polylines, trim
from foldfab.printing.marks import alignment_marks, crop_marks, legend, scale_bar, tile_map
from foldfab.printing.model_view import model_view
from foldfab.printing.page import Lines, Page, Shape, Text, rect
from foldfab.printing.paper import PrintOptions, check_options
from foldfab.printing.styles import MARKS, LineStyle, line_styles
from foldfab.printing.tiles import FOOTER, Tiling, tile_patterns

LINE = 4.2
"""mm between lines of 8-9 pt text."""


@dataclass(frozen=True)
class Template:
    """The pages of a template and where each tile went: ``tiles[i]`` is the tiling of
    piece ``i``, whose tile (row, col) is page ``first_page[i] + row * cols + col`` (0-based;
    page 0 is the first page, with the model)."""

    pages: list[Page]
    tilings: list[Tiling]
    first_page: list[int]
    scale_bars: list[tuple[float, float]]    # page mm: the bar's bottom-left corner on every page

    def page_of(self, piece: int, row: int, col: int) -> int:
        return self.first_page[piece] + row * self.tilings[piece].cols + col


def fold_counts(cp: CreasePattern) -> dict[str, tuple[int, float]]:
    """Edges and their length (mm) by assignment."""
    lengths = cp.edge_lengths
    return {kind: (int((cp.assignment == kind).sum()), float(lengths[cp.assignment == kind].sum()))
            for kind in ("M", "V", "F", "B")}


def _bounds(cp: CreasePattern) -> tuple[float, float, float, float]:
    lo, hi = cp.vertices.min(axis=0), cp.vertices.max(axis=0)
    return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])


def build_template(design, options: PrintOptions, pieces: Sequence[Piece] = ()) -> Template:
    """The template of a design: whole, or its ``pieces`` when it is split across sheets."""
    if not pieces:
        return lay_out([design.crease_pattern], design.job.name, design.crease_pattern, design.grid.closed, options)
    return lay_out([p.crease_pattern for p in pieces], design.job.name, design.crease_pattern, design.grid.closed,
                   options, [p.marks for p in pieces], [p.joins for p in pieces])


def lay_out(pieces: list[CreasePattern], name: str, model: CreasePattern, closed: bool,
            options: PrintOptions, marks: Sequence[Sequence[np.ndarray]] = (),
            joins: Sequence[Sequence[Join]] = ()) -> Template:
    """The pages of ``pieces`` (crease patterns, each on its own pages), the folded ``model``
    and folding notes on the first page; ``marks[i]`` are piece ``i``'s match-mark strokes
    (crease-pattern mm) and ``joins[i]`` its tabs and edges, named on its pages and in the notes."""
    check_options(options)
    marks = list(marks) or [()] * len(pieces)
    glued = _glued_text(joins) if joins else [""] * len(pieces)
    tilings = tile_patterns([_bounds(cp) for cp in pieces], options.paper, options.turnable, options.margin,
                            options.overlap, options.scale, options.paper_name)
    styles = line_styles(options.mono, options.flat)
    total = 1 + sum(t.count for t in tilings)
    paper = tilings[0].paper
    first = [1]
    for t in tilings[:-1]:
        first.append(first[-1] + t.count)
    pages = [_first_page(pieces, tilings, first, name, model, closed, styles, options, total, joins)]
    for index, (cp, tiling) in enumerate(zip(pieces, tilings)):
        polylines = crease_polylines(cp, tuple(styles))
        boxes = {kind: _boxes(lines) for kind, lines in polylines.items()}
        arcs: dict[tuple[str, int], np.ndarray] = {}  # arc lengths of the polylines trimmed, found as needed
        piece = f"piece {index + 1} of {len(pieces)}  ·  " if len(pieces) > 1 else ""
        info = _info(cp, options.scale)
        strokes = list(marks[index])
        legend_styles = {**styles, "marks": MARKS} if strokes else styles
        for row in range(tiling.rows):
            for col in range(tiling.cols):
                page = Page(*paper)
                _tile(page, tiling, row, col, polylines, arcs, boxes, styles)
                _marks(page, tiling, row, col, strokes)
                number = len(pages) + 1
                _header(page, options.margin, f"{name}  ·  {piece}row {row + 1} of {tiling.rows}, "
                                              f"column {col + 1} of {tiling.cols}", f"page {number} of {total}")
                _footer(page, options.margin, legend_styles, info, tiling, row, col, glued[index])
                pages.append(page)
    bar = (options.margin, options.margin + 2.0)
    return Template(pages, tilings, first, [bar] * len(pages))


def _boxes(polylines: list[np.ndarray]) -> np.ndarray:
    """The bounding box (x0, y0, x1, y1) of every polyline: (n, 4)."""
    if not polylines:
        return np.zeros((0, 4))
    return np.array([[*p.min(axis=0), *p.max(axis=0)] for p in polylines])


def _tile(page: Page, tiling: Tiling, row: int, col: int, polylines: dict[str, list[np.ndarray]],
          arcs: dict[tuple[str, int], np.ndarray], boxes: dict[str, np.ndarray], styles: dict[str, LineStyle]) -> None:
    """The parts of the pattern's polylines that reach into tile (row, col), clipped to its
    area (a line element runs the whole length of the pattern: only its part near the tile is
    drawn, with its dashes where they fall on the whole line); the marks."""
    wx0, wy0, wx1, wy1 = tiling.window(row, col)
    for kind in ("F", "V", "M", "B"):  # the cut outline last, on top
        if kind not in styles:
            continue
        box = boxes[kind]
        inside = np.nonzero((box[:, 0] <= wx1) & (box[:, 2] >= wx0) & (box[:, 1] <= wy1) & (box[:, 3] >= wy0))[0] \
            if len(box) else []
        if len(inside):
            style = styles[kind]
            period = sum(style.dash) / tiling.scale
            within = (box[inside, 0] >= wx0) & (box[inside, 2] <= wx1) & (box[inside, 1] >= wy0) & (box[inside, 3] <= wy1)
            lines = polylines[kind]
            parts = [lines[i] if whole or len(lines[i]) == 2 else
                     trim(lines[i], _arc(arcs, lines, kind, i), (wx0, wy0, wx1, wy1), period)
                     for i, whole in zip(inside.tolist(), within.tolist())]
            parts = [part for part in parts if len(part) > 1]
            if parts:
                moved = tiling.to_page(np.concatenate(parts), row, col)
                parts = np.split(moved, np.cumsum([len(part) for part in parts[:-1]]))
                page.items.append(Lines(parts, style.color, style.width, style.dash, clip=tiling.area))
    page.items.append(crop_marks(tiling))
    page.items.append(alignment_marks(tiling, row, col))


def _marks(page: Page, tiling: Tiling, row: int, col: int, strokes: list[np.ndarray]) -> None:
    """The match marks (a piece's number, its tabs' and edges' letters) that reach into tile (row, col)."""
    wx0, wy0, wx1, wy1 = tiling.window(row, col)
    near = [s for s in strokes if s[:, 0].min() <= wx1 and s[:, 0].max() >= wx0
            and s[:, 1].min() <= wy1 and s[:, 1].max() >= wy0]
    if near:
        page.items.append(Lines([tiling.to_page(s, row, col) for s in near], MARKS.color, MARKS.width,
                                clip=tiling.area))


def _glued_text(joins: Sequence[Sequence[Join]]) -> list[str]:
    """For each piece, a line naming the piece each of its tabs and edges is glued to."""
    tabs = {j.letter: number for number, piece in enumerate(joins, 1) for j in piece if j.tab}
    edges = {j.letter: number for number, piece in enumerate(joins, 1) for j in piece if not j.tab}
    return ["  ·  ".join([f"tab {j.letter} goes under piece {edges[j.letter]}" for j in piece
                          if j.tab and j.letter in edges]
                         + [f"edge {j.letter} takes the tab of piece {tabs[j.letter]}" for j in piece
                            if not j.tab and j.letter in tabs])
            for piece in joins]


def _arc(arcs: dict[tuple[str, int], np.ndarray], lines: list[np.ndarray], kind: str, i: int) -> np.ndarray:
    if (kind, i) not in arcs:
        arcs[kind, i] = arc_lengths(lines[i])
    return arcs[kind, i]


def _info(cp: CreasePattern, scale: float) -> str:
    counts = fold_counts(cp)
    w, h = cp.sheet_size
    printed = f"{w * scale:.1f} x {h * scale:.1f} mm" + (f" (scale {scale:g} of {w:.1f} x {h:.1f} mm)"
                                                          if scale != 1 else "")
    return (f"sheet {printed}  ·  {counts['V'][0]} valley, {counts['M'][0]} mountain folds"
            + (f", {counts['F'][0]} flat creases" if counts["F"][0] else ""))


def _header(page: Page, margin: float, left: str, right: str) -> None:
    y = page.height - margin - 3.0
    page.items.append(Text(margin, y, left, size=8.0, bold=True))
    page.items.append(Text(page.width - margin, y, right, size=8.0, anchor="end"))


def _footer(page: Page, margin: float, styles: dict[str, LineStyle], info: str, tiling: Tiling | None,
            row: int | None, col: int | None, glued: str = "") -> None:
    """Scale bar, legend and the sheet's facts (and a piece's tabs and edges); the tile map on the right."""
    map_width = 36.0
    text_width = page.width - 2 * margin - (map_width + 4.0 if tiling else 0.0)
    page.items += scale_bar(margin, margin + 2.0)
    page.items += legend(margin, margin + 9.0, styles, text_width)
    page.items.append(Text(margin, margin + 16.0, info, size=7.0))
    if glued:
        page.items.append(Text(margin, margin + 20.0, glued, size=7.0))
    if tiling is not None:
        box = (page.width - margin - map_width, margin, page.width - margin, margin + FOOTER - 13.0)
        page.items += tile_map(tiling, row, col, box)
        page.items.append(Text(box[0], box[3] + 2.0, f"{tiling.rows} x {tiling.cols} pages"
                               + (f": row {row + 1}, column {col + 1}" if row is not None else ""), size=6.5))


MAX_JOIN_NOTES = 12
"""The most tabs the first page's notes name one by one."""


def folding_notes(pieces: list[CreasePattern], tilings: list[Tiling], closed: bool,
                  joins: Sequence[Sequence[Join]] = (), seam_tab: bool | None = None) -> list[str]:
    """What to do with the printed pages, in order; ``seam_tab``: the whole design has a seam
    tab (default: a piece has tab faces)."""
    notes = ["Print at 100 % (no 'fit to page'): the scale bar on every page must measure 50 mm."]
    if any(t.count > 1 for t in tilings):
        notes.append("Trim each page at the crop marks on its left and top edges where it has a neighbour, lay it "
                     "over that neighbour so the round targets meet, and tape it.")
    notes += ["Cut along the solid outline.",
              "Score every fold line with a stylus or an empty ball-point pen along a ruler.",
              "Fold all valley folds (dashed) first, then the mountain folds (dash-dot), then fold them together."]
    if seam_tab is None:
        seam_tab = any(cp.tab_faces.any() for cp in pieces)
    seam_lettered = seam_tab and any(j.across == 0 for piece in joins for j in piece)  # cut at mirrors: a letter
    if seam_tab and not seam_lettered:
        notes.append("The glue tab is the strip at the right end, past the last fold line: glue it under the "
                     "left end of the pattern so that the column closes.")
    elif closed and not seam_tab:
        notes.append("The two ends of the pattern meet when folded: tape them edge to edge.")
    if len(pieces) > 1:
        notes.append("Glue each piece's tab under the edge of the next piece that carries the same letter"
                     + _join_list(joins) + ".")
    return notes


def _join_list(joins: Sequence[Sequence[Join]]) -> str:
    """Which tab meets which edge: ": tab A of piece 1 under edge A of piece 2, ..." (the first
    :data:`MAX_JOIN_NOTES`)."""
    edges = {j.letter: number for number, piece in enumerate(joins, 1) for j in piece if not j.tab}
    pairs = [(j.letter, number, edges[j.letter]) for number, piece in enumerate(joins, 1) for j in piece
             if j.tab and j.letter in edges]
    if not pairs:
        return ""
    named = [f"tab {letter} of piece {a} under edge {letter} of piece {b}" for letter, a, b in pairs[:MAX_JOIN_NOTES]]
    return ": " + ", ".join(named) + (", and so on" if len(pairs) > MAX_JOIN_NOTES else "")


def _first_page(pieces, tilings, first, name, model, closed, styles, options, total, joins) -> Page:
    """The folded model, the facts, the notes and a map of every page over the pattern."""
    paper = tilings[0].paper
    page = Page(*paper)
    m = options.margin
    top = page.height - m
    page.items.append(Text(m, top - 6.0, name, size=14.0, bold=True))
    page.items.append(Text(page.width - m, top - 6.0, f"page 1 of {total}", size=8.0, anchor="end"))
    lines = [_info(cp, options.scale) + (f"  (piece {i + 1})" if len(pieces) > 1 else "")
             for i, cp in enumerate(pieces)]
    pages = sum(t.count for t in tilings)
    lines.append(f"printed on {pages} page{'s' * (pages != 1)} of {options.paper_name} after this one, "
                 f"{m:g} mm margins, {options.overlap:g} mm overlap between pages")
    y = top - 12.0
    for line in lines:
        page.items.append(Text(m, y, line, size=8.0))
        y -= LINE
    usable = y - (m + FOOTER)
    model_top, model_height = y - 2.0, usable * 0.42
    page.items += model_view(model, (m, model_top - model_height, page.width - m, model_top))
    y = model_top - model_height - 6.0
    chars = int((page.width - 2 * m) / (8.0 * 0.5 * 25.4 / 72))
    for i, note in enumerate(folding_notes(pieces, tilings, closed, joins, bool(model.tab_faces.any()))):
        for k, line in enumerate(textwrap.wrap(note, chars - 4)):
            page.items.append(Text(m + 4.0 if k else m, y, (f"{i + 1}. " if not k else "") + line, size=8.0))
            y -= LINE
    _overview(page, pieces, tilings, first, (m, m + FOOTER + 2.0, page.width - m, y - 2.0))
    _footer(page, m, styles, "the folded model, seen from in front and above", None, None, None)
    return page


def _overview(page: Page, pieces, tilings, first, box) -> None:
    """Every piece's outline, stacked in ``box``, with its tiles and their page numbers."""
    x0, y0, x1, y1 = box
    if y1 - y0 < 10.0:
        return
    spans = [(t.cols * t.step[0] + (t.area[2] - t.area[0] - t.step[0]),
              t.rows * t.step[1] + (t.area[3] - t.area[1] - t.step[1])) for t in tilings]
    fit = min((x1 - x0) / max(w for w, _ in spans), (y1 - y0) / sum(h for _, h in spans) * 0.95)
    top = y1
    for cp, tiling, start, (w, h) in zip(pieces, tilings, first, spans):
        left = x0 + ((x1 - x0) - w * fit) / 2
        to_box = np.array([left, top]) - np.array(tiling.origin) * fit
        outline = [p * tiling.scale * fit + to_box for p in crease_polylines(cp, ("B",))["B"]]
        page.items.append(Lines(outline, "#000000", 0.2))
        aw, ah = tiling.area[2] - tiling.area[0], tiling.area[3] - tiling.area[1]
        for r in range(tiling.rows):
            for c in range(tiling.cols):
                tx, ty = left + c * tiling.step[0] * fit, top - r * tiling.step[1] * fit
                page.items.append(Shape(rect(tx, ty - ah * fit, tx + aw * fit, ty), stroke="#808080", width=0.15))
                page.items.append(Text(tx + aw * fit / 2, ty - ah * fit / 2 - 1.0, str(start + r * tiling.cols + c + 1),
                                       size=min(8.0, aw * fit), anchor="middle"))
        top -= h * fit * 1.05
