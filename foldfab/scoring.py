"""Scoring geometry: which lines of a crease pattern the plotter draws, per fold type.

Pure geometry in crease-pattern millimetres (x right, y up): the creases of each
assignment as segments, the sheet outline as closed loops, and perforation
dashes as real cut segments.  Flat creases are never scored.
"""

from __future__ import annotations

import numpy as np

from foldfab.crease_pattern import CreasePattern


def crease_lines(cp: CreasePattern, kind: str) -> list[np.ndarray]:
    """The creases assigned ``kind`` ("M" or "V") chained into polylines (complex arrays).

    Chaining along the crease pattern's own vertex numbering is exact and cheap; vpype's
    ``linemerge`` then only has the joins between chains left to find.
    """
    return _chains(cp, cp.edges[cp.assignment == kind])


def outline_loops(cp: CreasePattern) -> list[np.ndarray]:
    """The border edges chained into closed loops (first point repeated at the end), as complex arrays."""
    return _chains(cp, cp.edges[cp.assignment == "B"])


def _chains(cp: CreasePattern, edges: np.ndarray) -> list[np.ndarray]:
    """``edges`` (E, 2 vertex indices) drawn with as few pen lifts as a graph allows.

    A connected set of edges with ``2k`` vertices of odd degree needs ``k`` strokes (one
    closed loop if ``k`` is 0), and that many suffice (Euler).  Hierholzer's algorithm
    finds them: an extra vertex joined to every odd vertex makes every degree even; the
    Euler circuits of that graph, cut where they pass the extra vertex, are the strokes.
    Closed loops repeat their first point.  Deterministic (neighbours in index order).
    """
    pairs = edges.tolist()
    odd = np.flatnonzero(np.bincount(edges.ravel(), minlength=len(cp.vertices)) % 2).tolist()
    extra = len(cp.vertices)
    pairs += [[v, extra] for v in odd]
    neighbours: dict[int, list[tuple[int, int]]] = {}
    for index, (a, b) in enumerate(pairs):
        neighbours.setdefault(a, []).append((b, index))
        neighbours.setdefault(b, []).append((a, index))
    for options in neighbours.values():
        options.sort()
    used = [False] * len(pairs)
    cursor = dict.fromkeys(neighbours, 0)
    points = cp.vertices[:, 0] + 1j * cp.vertices[:, 1]
    walks: list[list[int]] = []
    starts = ([extra] if odd else []) + sorted(min(a, b) for a, b in edges.tolist())
    for start in starts:
        circuit, stack = [], [start]
        while stack:  # Hierholzer: extend the walk; at a dead end, emit the vertex and back up
            v = stack[-1]
            options, i = neighbours[v], cursor[v]
            while i < len(options) and used[options[i][1]]:
                i += 1
            cursor[v] = i
            if i < len(options):
                used[options[i][1]] = True
                stack.append(options[i][0])
            else:
                circuit.append(stack.pop())
        piece: list[int] = []
        for v in circuit + [extra]:
            if v == extra:
                if len(piece) > 1:
                    walks.append(piece)
                piece = []
            else:
                piece.append(v)
    return [points[walk] for walk in walks]


def perforate(segments: np.ndarray, pattern: tuple[float, ...], clearance: float) -> np.ndarray:
    """Dashes (D, 2) complex cutting each segment by ``pattern`` (cut, gap, cut, gap ...) mm.

    The pattern starts ``clearance`` mm after a segment's start and every dash is
    clipped ``clearance`` mm before its end, so crease vertices are never cut out.
    """
    pattern = np.asarray(pattern, dtype=float)
    period = pattern.sum()
    offsets = np.concatenate([[0.0], np.cumsum(pattern)])[:-1]
    dash_start, dash_len = offsets[0::2], pattern[0::2]
    a, b = segments[:, 0], segments[:, 1]
    length = np.abs(b - a)
    usable = length - 2.0 * clearance
    ok = usable > 0
    a, b, length, usable = a[ok], b[ok], length[ok], usable[ok]
    repeats = np.ceil(usable / period).astype(int)
    seg = np.repeat(np.arange(len(a)), repeats)
    k = np.arange(repeats.sum()) - np.repeat(np.cumsum(repeats) - repeats, repeats)
    start = clearance + k[:, None] * period + dash_start[None, :]    # (N, dashes per period)
    end = np.minimum(start + dash_len[None, :], (clearance + usable[seg])[:, None])
    seg = np.broadcast_to(seg[:, None], start.shape)
    keep = end > start + 1e-9
    s, e, sg = start[keep], end[keep], seg[keep]
    direction = (b - a) / length
    return np.column_stack([a[sg] + s * direction[sg], a[sg] + e * direction[sg]])
