"""A crease pattern split into pieces that each fit a sheet, joined again by glue tabs.

Cuts run only along creases that cross the whole pattern, so every join is hidden in a fold:
along mirror creases (plane ``k`` of the grid, 0 < k < K, each from the top border to the
bottom) and along line-element creases (line element ``j``, 0 < j < J-1, each from one end of
the strip to the other).  Every cut gets a glue tab on one side only, the piece before the cut
(left of a mirror cut, below a line-element cut): the tab is the neighbouring panel's strip
next to the cut, copied onto this piece by :func:`~foldfab.geometry.crease_pattern.tab_edge`,
the rule and code of the closed design's seam tab.  A piece is a sub-grid of the design's
grid, built with the design's own face normals, so its creases are the design's exactly.
Pure geometry: no I/O.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from foldfab.errors import DesignError
from foldfab.geometry.crease_pattern import CreasePattern, face_normals, grid_pattern, tab_edge, tabbed_grid
from foldfab.geometry.reflection import Reflection
from foldfab.geometry.stroke_font import text_strokes

DEFAULT_TAB = 8.0
"""mm: the width of a split's glue tabs when the design sets no ``[crease].glue_tab`` (at most
half the neighbouring panel's narrowest width)."""
MARK_HEIGHT = 5.0
"""mm: the largest letter of a match mark; smaller where the tab is narrower."""


@dataclass(frozen=True)
class Join:
    """One side of a cut: the piece with the tab, or the piece with the edge the tab glues to."""

    letter: str
    tab: bool                 # this piece carries the tab (else: the edge it glues to)
    line: np.ndarray          # (N, 2) the cut line, piece coordinates
    across: int               # sheet axis the tab's strip runs from the line: 0 (+x) or 1 (+y)
    width: float              # mm, the tab's width
    outline: np.ndarray | None = None   # (M, 2) the tab's polygon (chamfered ends), piece coordinates; None: an edge


@dataclass(frozen=True)
class Piece:
    """One sheet's part of a split design, in its own coordinates: ``crease_pattern.vertices +
    offset`` are the whole design's crease-pattern coordinates."""

    number: int               # 1-based
    count: int
    rows: tuple[int, int]     # line elements ja..jb it spans
    columns: tuple[int, int]  # planes ka..kb it spans
    crease_pattern: CreasePattern
    offset: np.ndarray        # (2,) mm
    joins: tuple[Join, ...]
    marks: tuple[np.ndarray, ...]   # strokes (N, 2) of the match marks, piece coordinates: drawn, never cut
    cut_tabs: np.ndarray      # (F,) bool: faces of the crease pattern that are the split's glue tabs

    @property
    def label(self) -> str:
        """The piece's number as its marks write it."""
        return f"{self.number} OF {self.count}"


def letters(n: int) -> list[str]:
    """Match-mark letters for ``n`` joins: A..Z, then AA, AB, ..."""
    out = []
    for i in range(n):
        name = ""
        i += 1
        while i:
            i, r = divmod(i - 1, 26)
            name = chr(65 + r) + name
        out.append(name)
    return out


def check_cuts(grid: Reflection, columns: list[int], rows: list[int], what_columns: str, what_rows: str) -> None:
    """Cuts must lie on creases that cross the whole pattern: mirror planes 1..K-1, line
    elements 1..J-2, each once; the error names the key (``what_columns``/``what_rows``)."""
    K, J = grid.x.shape[1] - 1, grid.x.shape[0]
    for values, high, what, kind in ((columns, K - 1, what_columns, "trajectory corners (mirror creases)"),
                                     (rows, J - 2, what_rows, "profile points (line-element creases)")):
        bad = [v for v in values if not 1 <= v <= high]
        if bad:
            span = f"from 1 to {high}" if high >= 1 else "none: the design has no such crease inside it"
            raise DesignError(f"{what}: {bad[0]} is not a cut this design has; it cuts after {kind}, {span}")
        if len(set(values)) != len(values):
            raise DesignError(f"{what}: {sorted(values)} names a cut twice; list each once")


def _tab_width(glue_tab: float, across: np.ndarray) -> float:
    """The width of a split's tab: ``glue_tab`` if the design sets one, else :data:`DEFAULT_TAB`
    or half the narrowest ``across`` width of the panel it lies on, whichever is smaller."""
    return glue_tab if glue_tab > 0 else min(DEFAULT_TAB, 0.5 * float(across.min()))


def split_pattern(grid: Reflection, flat_angle: float, glue_tab: float, columns: list[int] = (),
                  rows: list[int] = ()) -> list[Piece]:
    """The design of ``grid`` cut after mirror planes ``columns`` and line elements ``rows`` into
    pieces, numbered row by row from the bottom left; tabs ``glue_tab`` mm wide (or
    :func:`_tab_width`).  The seam tab of a closed design stays on the last piece of each row."""
    check_cuts(grid, list(columns), list(rows), "[fabrication].split", "[fabrication].split_height")
    x, heights, points, seam = tabbed_grid(grid, glue_tab)
    y, tol = grid.arc, grid.tolerance
    J, C = x.shape
    K = grid.x.shape[1] - 1
    normals = face_normals(points)
    col_bounds = [0, *sorted(columns), K]
    row_bounds = [0, *sorted(rows), J - 1]
    ncol, nrow = len(col_bounds) - 1, len(row_bounds) - 1
    names = iter(letters((ncol - 1 + (seam and ncol > 1)) * nrow + (nrow - 1) * ncol))
    vletter = {(r, c): next(names) for r in range(nrow) for c in range(ncol - 1 + (seam and ncol > 1))}
    hletter = {(r, c): next(names) for r in range(nrow - 1) for c in range(ncol)}
    pieces = []
    for r in range(nrow):
        for c in range(ncol):
            ja, jb = row_bounds[r], row_bounds[r + 1]
            ka, kb = col_bounds[c], col_bounds[c + 1]
            last = C - 1 if c == ncol - 1 else kb
            xs, ps, ys = x[ja:jb + 1, ka:last + 1], points[ja:jb + 1, ka:last + 1], heights[ja:jb + 1, ka:last + 1]
            jj, kk = np.meshgrid(np.arange(ja, jb), np.arange(ka, last), indexing="ij")
            ids, tab_col = np.stack([jj, kk], axis=-1), kk >= K
            widths, outlines = {}, {}
            if seam and c == ncol - 1:   # the seam tab as it is, chamfered at the design's top and bottom
                outlines["v"] = np.vstack([np.column_stack([x[ja:jb + 1, K], y[ja:jb + 1]]),
                                           np.column_stack([xs[:, -1], ys[:, -1]])[::-1]])
            if c < ncol - 1:  # tab past the mirror cut at plane kb, on the next piece's first panel
                edge = np.column_stack([x[ja:jb + 1, kb + 1] - x[ja:jb + 1, kb], np.zeros(jb - ja + 1)])
                widths["v"] = w = _tab_width(glue_tab, np.abs(edge[:, 0]))
                cut = np.column_stack([x[ja:jb + 1, kb], y[ja:jb + 1]])
                far, far_3d = tab_edge(cut, edge, points[ja:jb + 1, kb],
                                       points[ja:jb + 1, kb + 1] - points[ja:jb + 1, kb], w, 0, tol,
                                       lambda i: f"segment {kb} of line element {ja + i} (after the split at plane {kb})")
                outlines["v"] = np.vstack([cut, far[::-1]])
                xs, ys = np.column_stack([xs, far[:, 0]]), np.column_stack([ys, far[:, 1]])
                ps = np.concatenate([ps, far_3d[:, None]], axis=1)
                ids = np.concatenate([ids, np.stack([np.arange(ja, jb), np.full(jb - ja, kb)], axis=-1)[:, None]], axis=1)
                tab_col = np.column_stack([tab_col, np.ones(jb - ja, bool)])
            tab_row = np.zeros_like(tab_col)
            if r < nrow - 1:  # tab past the line-element cut at jb, on the next piece's first row
                n = last - ka + 1
                edge = np.column_stack([x[jb + 1, ka:last + 1] - x[jb, ka:last + 1], heights[jb + 1, ka:last + 1] - y[jb]])
                widths["h"] = w = _tab_width(glue_tab, np.abs(edge[:, 1]))
                cut = np.column_stack([x[jb, ka:last + 1], np.full(n, y[jb])])
                far, far_3d = tab_edge(cut, edge,
                                       points[jb, ka:last + 1], points[jb + 1, ka:last + 1] - points[jb, ka:last + 1],
                                       w, 1, tol, lambda i: f"profile segment {jb} (after the split at profile point {jb})")
                outlines["h"] = np.vstack([cut, far[::-1]])
                if xs.shape[1] > n:   # the corner past both tabs: no face, any point on the row's line
                    far = np.vstack([far, [far[-1, 0] + xs[-1, -1] - xs[-1, -2], far[-1, 1]]])
                    far_3d = np.vstack([far_3d, far_3d[-1]])
                xs = np.vstack([xs, far[:, 0]])
                ps = np.concatenate([ps, far_3d[None]], axis=0)
                ys = np.vstack([ys, far[:, 1]])
                cols = np.append(np.arange(ka, last), np.full(xs.shape[1] - 1 - (last - ka), kb))
                ids = np.concatenate([ids, np.stack([np.full(len(cols), jb), cols], axis=-1)[None]], axis=0)
                tab_col = np.vstack([tab_col, tab_col[-1]])
                tab_row = np.zeros_like(tab_col)
                tab_row[-1] = True
            # The corner past both a split's tab column and tab row is no face; the tab row
            # does go on under the seam tab, so that the seam tab's folds stay in one piece.
            split_col = np.zeros_like(tab_col)
            if c < ncol - 1:
                split_col[:, -1] = True
            keep = ~(tab_row & split_col)
            cp = grid_pattern(xs, ys, ps, flat_angle, ids, tab_row | tab_col, keep, normals[ids[..., 0], ids[..., 1]])
            origin = cp.vertices.min(axis=0)
            joins = []

            def line(j0: int, j1: int, k0: int, k1: int) -> np.ndarray:
                """A cut line in piece coordinates: line elements j0..j1 at planes k0..k1."""
                block = np.broadcast_to(y[j0:j1 + 1, None], (j1 + 1 - j0, k1 + 1 - k0))
                return np.column_stack([x[j0:j1 + 1, k0:k1 + 1].ravel(), block.ravel()]) - origin
            if (r, c) in vletter:
                joins.append(Join(vletter[r, c], True, line(ja, jb, kb, kb), 0, widths.get("v", glue_tab),
                                  outlines["v"] - origin))
            if c > 0 or (seam and ncol > 1):
                edge_c = c - 1 if c > 0 else ncol - 1
                joins.append(Join(vletter[r, edge_c], False, line(ja, jb, ka, ka), 0,
                                  widths.get("v", glue_tab)))
            if (r, c) in hletter:
                joins.append(Join(hletter[r, c], True, line(jb, jb, ka, kb), 1, widths["h"], outlines["h"] - origin))
            if r > 0:
                joins.append(Join(hletter[r - 1, c], False, line(ja, ja, ka, kb), 1, 0.0))
            pieces.append((r, c, ja, jb, ka, kb, cp, origin, joins, (tab_row | split_col)[keep]))
    count = len(pieces)
    # An edge's strip is as wide as the tab glued to it.
    tab_widths = {j.letter: j.width for p in pieces for j in p[8] if j.tab}
    out = []
    for number, (r, c, ja, jb, ka, kb, cp, origin, joins, cut_tabs) in enumerate(pieces, 1):
        joins = [replace(j, width=tab_widths.get(j.letter, j.width)) for j in joins]
        shifted = CreasePattern(cp.vertices - origin, cp.vertices_3d, cp.faces, cp.face_grid, cp.edges,
                                cp.assignment, cp.fold_angle, cp.edges_faces, cp.tab_faces)
        marks = match_marks(joins, f"{number} OF {count}") if count > 1 else ()
        out.append(Piece(number, count, (ja, jb), (ka, kb), shifted, origin, tuple(joins), tuple(marks), cut_tabs))
    return out


def auto_cuts(grid: Reflection, glue_tab: float, fits: Callable[[float, float], bool],
              rows: list[int] | None = None) -> tuple[list[int], list[int]]:
    """The cuts (mirror planes, line elements) that split the design into few pieces for which
    ``fits(width, height)`` (mm, tabs included) holds, as even as possible: the fewest rows
    that fit, with the tallest as low as can be, then the fewest columns, with the widest piece
    as narrow as can be.  ``rows``: line-element cuts already chosen.  No cuts when the whole
    design fits; a design with a panel that fits no sheet is an error."""
    x, _, _, _ = tabbed_grid(grid, glue_tab)
    y, J, K = grid.arc, len(grid.arc), grid.x.shape[1] - 1
    tab = glue_tab if glue_tab > 0 else DEFAULT_TAB   # the most a split's tab may add

    def width(ja: int, jb: int, ka: int, kb: int) -> float:
        far = x[ja:jb + 1, x.shape[1] - 1 if kb == K else kb]
        return float(far.max() - x[ja:jb + 1, ka].min()) + (tab if kb < K else 0.0)

    def height(ja: int, jb: int) -> float:
        return float(y[jb] - y[ja]) + (tab if jb < J - 1 else 0.0)

    if rows is None:
        rows = _balanced(J - 1, lambda a, b, cap: height(a, b) <= cap and fits(0.0, height(a, b)), height)
    if rows is not None:
        blocks = list(zip([0, *rows], [*rows, J - 1]))
        columns = _balanced(K, lambda a, b, cap: all(w <= cap and fits(w, height(ja, jb))
                                                     for ja, jb in blocks for w in [width(ja, jb, a, b)]),
                            lambda a, b: max(width(ja, jb, a, b) for ja, jb in blocks))
        if columns is not None:
            return columns, rows
    raise DesignError("[fabrication].split: even one panel of the crease pattern does not fit the sheet at this "
                      "scale; use a smaller scale, a larger sheet or a smaller margin")


def _greedy(n: int, ok: Callable[[int, int], bool]) -> list[int] | None:
    """Cuts in 1..n-1 taking each piece [a, b] as far as ``ok(a, b)`` allows (sizes grow with b,
    so it fails for every b past its first failure); None if a single step fails."""
    cuts, a = [], 0
    while True:
        b = a
        while b < n and ok(a, b + 1):
            b += 1
        if b == a:
            return None
        if b == n:
            return cuts
        cuts.append(b)
        a = b


def _balanced(n: int, ok: Callable[[int, int, float], bool], size: Callable[[int, int], float]) -> list[int] | None:
    """:func:`_greedy` into the fewest pieces, under the lowest cap on ``size`` that keeps that
    count (bisection): the pieces as even as the creases allow."""
    fewest = _greedy(n, lambda a, b: ok(a, b, np.inf))
    if fewest is None:
        return None
    low, high = 0.0, size(0, n)
    for _ in range(40):
        cap = (low + high) / 2
        cuts = _greedy(n, lambda a, b: ok(a, b, cap))
        if cuts is not None and len(cuts) <= len(fewest):
            high = cap
        else:
            low = cap
    return _greedy(n, lambda a, b: ok(a, b, high))


def match_marks(joins: list[Join], label: str) -> list[np.ndarray]:
    """Strokes writing each join's letter in the strip along its cut line (on the tab, inside its
    chamfered outline, or where the tab will cover the edge), and the piece's ``label`` after
    the letter of its first join."""
    strokes: list[np.ndarray] = []
    for index, join in enumerate(joins):
        text = join.letter + (f" {label}" if index == 0 else "")
        glyphs = text_strokes(text, 1.0)
        ratio = max(float(g[:, 0].max()) for g in glyphs)   # text length per mm of height
        best: list[np.ndarray] = []
        best_height = 0.0
        for centre, along, up, height in _text_places(join, ratio):
            for _ in range(SHRINKS):   # smaller about its centre until it lies on the tab
                if height <= best_height:
                    break
                start = centre - along * ratio * height / 2 - up * height / 2
                placed = [start + np.outer(g[:, 0] * height, along) + np.outer(g[:, 1] * height, up) for g in glyphs]
                if join.outline is None or _inside(np.concatenate(placed), join.outline).all():
                    best, best_height = placed, height
                    break
                height *= 0.8
        strokes += best
    return strokes


SHRINKS = 12
"""How many times a match mark is made smaller (by 0.8 each) to fit inside a chamfered tab."""


def _inside(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Whether each point lies inside ``polygon`` (even-odd rule; any simple polygon)."""
    a, b = polygon, np.roll(polygon, -1, axis=0)
    px, py = points[:, 0, None], points[:, 1, None]
    spans = (a[:, 1] > py) != (b[:, 1] > py)
    dy = np.where(b[:, 1] != a[:, 1], b[:, 1] - a[:, 1], 1.0)
    cross_x = a[:, 0] + (py - a[:, 1]) * (b[:, 0] - a[:, 0]) / dy
    return (spans & (px < cross_x)).sum(axis=1) % 2 == 1


def _text_places(join: Join, ratio: float) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, float]]:
    """Where text ``ratio`` times as long as high fits largest inside the strip ``join.width``
    wide beside the cut line: (centre, direction, up, height) of each place, largest first.

    Each segment of the cut line offers two places, centred on it: text straight across the
    strip's axis, or text along the segment.  A point ``mid + σ·d + τ·n`` of text along
    direction ``d`` (up ``n``) is ``a + (L/2 + σ + τα)·d + (w/2 + τβ)·across`` in the strip's own
    coordinates, with ``n = α·d + β·across``: it stays inside while ``|τβ| <= w/2`` and
    ``|σ| + |τα| <= L/2``."""
    across = np.eye(2)[join.across]
    places = []
    for a, b in zip(join.line[:-1], join.line[1:]):
        seg = b - a
        length = float(np.linalg.norm(seg))
        if length <= 0:
            continue
        straight = np.array([0.0, -1.0]) if join.across == 0 else np.array([1.0, 0.0])
        for d in (straight, seg / length):
            n = np.array([-d[1], d[0]])
            if np.dot(n, across) < 0:
                d, n = -d, -n
            # n = alpha d + beta across, in the strip's (segment, across) coordinates
            basis = np.column_stack([seg / length, across])
            if abs(np.linalg.det(basis)) < 1e-12:
                continue
            alpha_d, beta = np.linalg.solve(basis, n)
            sigma_d, sigma_a = np.linalg.solve(basis, d)   # d itself, in the same coordinates
            # the half-extents: text of height h and length r*h, centred at the strip's middle
            # needs h/2*|beta| + r*h/2*|sigma_a| <= w/2 and h/2*|alpha_d| + r*h/2*|sigma_d| <= L/2
            cap_w = join.width / max(abs(beta) + ratio * abs(sigma_a), 1e-300)
            cap_l = length / max(abs(alpha_d) + ratio * abs(sigma_d), 1e-300)
            height = 0.8 * min(MARK_HEIGHT / 0.8, cap_w, cap_l)
            if height > 0:
                places.append(((a + b) / 2 + across * join.width / 2, d, n, height))
    return sorted(places, key=lambda place: -place[3])
