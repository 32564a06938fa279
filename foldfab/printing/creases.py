"""A crease pattern's edges joined into straight-on polylines per kind, so that a dash
pattern runs on along a whole crease instead of restarting at every vertex (a mirror crease
of a fine profile is thousands of edges shorter than one dash)."""

from __future__ import annotations

from collections import defaultdict

import numpy as np

from foldfab.geometry.crease_pattern import CreasePattern

STRAIGHT = 0.5
"""Cosine of the largest turn a polyline takes at a vertex (60 degrees): a mirror crease
zigzags gently, while a line element crossing it turns 90 degrees or more."""


def crease_polylines(cp: CreasePattern, kinds: tuple[str, ...]) -> dict[str, list[np.ndarray]]:
    """The edges of each kind in ``kinds`` (B, M, V, F) as polylines of crease-pattern points:
    every edge in exactly one polyline, each polyline turning by at most 60 degrees at a vertex."""
    return {kind: _chain(cp.vertices, cp.edges[cp.assignment == kind]) for kind in kinds}


def _chain(vertices: np.ndarray, edges: np.ndarray) -> list[np.ndarray]:
    """Greedy walk: from each unused edge, extend both ways along the straightest unused edge."""
    if not len(edges):
        return []
    direction = vertices[edges[:, 1]] - vertices[edges[:, 0]]
    length = np.hypot(direction[:, 0], direction[:, 1])
    unit = (direction / np.where(length > 0, length, 1.0)[:, None]).tolist()
    at: dict[int, list[int]] = defaultdict(list)
    ends = edges.tolist()
    for e, (a, b) in enumerate(ends):
        at[a].append(e)
        at[b].append(e)
    used = [False] * len(ends)
    out = []
    for first in range(len(ends)):
        if used[first]:
            continue
        used[first] = True
        a, b = ends[first]
        forward = _walk(ends, unit, at, used, first, b, 1.0)
        backward = _walk(ends, unit, at, used, first, a, -1.0)
        out.append(backward[::-1] + [a, b] + forward)
    return [vertices[chain] for chain in out]


def _walk(ends: list, unit: list, at: dict, used: list, edge: int, vertex: int, sign: float) -> list[int]:
    """Vertices reached from ``vertex`` (the end of ``edge``, run in direction ``sign``)."""
    path = []
    hx, hy = unit[edge][0] * sign, unit[edge][1] * sign
    while True:
        best, best_cos, best_sign = -1, STRAIGHT, 1.0
        for e in at[vertex]:
            if used[e]:
                continue
            s = 1.0 if ends[e][0] == vertex else -1.0
            ux, uy = unit[e]
            c = (ux * hx + uy * hy) * s
            if c > best_cos:
                best, best_cos, best_sign = e, c, s
        if best < 0:
            return path
        used[best] = True
        vertex = ends[best][1] if best_sign > 0 else ends[best][0]
        hx, hy = unit[best][0] * best_sign, unit[best][1] * best_sign
        path.append(vertex)


def arc_lengths(line: np.ndarray) -> np.ndarray:
    """Cumulative length (n,) along a polyline from its first point."""
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(line, axis=0).T))])


def trim(line: np.ndarray, arc: np.ndarray, window: tuple[float, float, float, float], period: float) -> np.ndarray:
    """The part of ``line`` (with :func:`arc_lengths` ``arc``) that may reach into ``window``,
    starting at a whole number of dash ``period`` from its start, so that a dash pattern drawn
    on the part falls exactly where it falls on the whole line (0: no dash, cut at a vertex)."""
    x0, y0, x1, y1 = window
    a, b = line[:-1], line[1:]
    reach = ((np.minimum(a[:, 0], b[:, 0]) <= x1) & (np.maximum(a[:, 0], b[:, 0]) >= x0)
             & (np.minimum(a[:, 1], b[:, 1]) <= y1) & (np.maximum(a[:, 1], b[:, 1]) >= y0))
    hits = np.nonzero(reach)[0]
    if not len(hits):
        return line[:0]
    first, last = int(hits[0]), int(hits[-1]) + 1
    if period <= 0 or first == 0:
        return line[first:last + 1]
    start = np.floor(arc[first] / period) * period
    k = int(np.searchsorted(arc, start, side="right")) - 1  # the segment holding the new start
    span = arc[k + 1] - arc[k]
    point = line[k] + (line[k + 1] - line[k]) * ((start - arc[k]) / span if span > 0 else 0.0)
    return np.concatenate([point[None], line[k + 1:last + 1]])
