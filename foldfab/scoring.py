"""Scoring geometry: which lines of a crease pattern the plotter draws, per fold type.

Pure geometry in crease-pattern millimetres (x right, y up): the creases of each
assignment as segments, the sheet outline as closed loops, and perforation
dashes as real cut segments.  Flat creases are never scored.
"""

from __future__ import annotations

import numpy as np

from foldfab.crease_pattern import CreasePattern


def crease_segments(cp: CreasePattern, kind: str) -> np.ndarray:
    """(S, 2) complex end points of every crease assigned ``kind`` ("M" or "V")."""
    p = cp.vertices[cp.edges[cp.assignment == kind]]
    return p[..., 0] + 1j * p[..., 1]


def outline_loops(cp: CreasePattern) -> list[np.ndarray]:
    """The border edges chained into closed loops (first point repeated at the end), as complex arrays."""
    edges = cp.edges[cp.assignment == "B"]
    neighbours: dict[int, list[int]] = {}
    for a, b in edges.tolist():
        neighbours.setdefault(a, []).append(b)
        neighbours.setdefault(b, []).append(a)
    loops = []
    unused = {tuple(sorted(e)) for e in edges.tolist()}
    points = cp.vertices[:, 0] + 1j * cp.vertices[:, 1]
    while unused:
        start = min(unused)[0]
        loop = [start]
        prev, cur = None, start
        while True:
            options = [n for n in neighbours[cur] if n != prev and tuple(sorted((cur, n))) in unused]
            if not options:
                break
            nxt = min(options)
            unused.discard(tuple(sorted((cur, nxt))))
            loop.append(nxt)
            prev, cur = cur, nxt
            if cur == start:
                break
        loops.append(points[loop])
    return loops


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
