"""Scoring geometry: which lines of a crease pattern the plotter draws, per fold type.

Pure geometry in crease-pattern millimetres (x right, y up): the creases of each
assignment as segments, the sheet outline as closed loops, and perforation
dashes as real cut segments.  Flat creases are never scored.
"""

from __future__ import annotations

from array import array
from itertools import chain

import numpy as np

from foldfab.geometry.crease_pattern import CreasePattern


def crease_lines(cp: CreasePattern, kind: str, points: np.ndarray | None = None) -> list[np.ndarray]:
    """The creases assigned ``kind`` ("M" or "V") chained into polylines (complex arrays).

    Chaining along the crease pattern's own vertex numbering is exact and cheap; vpype's
    ``linemerge`` then only has the joins between chains left to find.  ``points`` gives
    each vertex's complex position (default: the crease pattern's own millimetres).
    """
    return split_strokes(*crease_strokes(cp, kind, points))


def outline_loops(cp: CreasePattern, points: np.ndarray | None = None) -> list[np.ndarray]:
    """The border edges chained into closed loops (first point repeated at the end), as complex
    arrays (``points`` as in :func:`crease_lines`)."""
    return split_strokes(*outline_strokes(cp, points))


def crease_strokes(cp: CreasePattern, kind: str,
                   points: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`crease_lines` as arrays: every polyline's points one after another (complex), and
    the index where each polyline starts; no Python object per line."""
    return _strokes(cp.edges[cp.assignment == kind], _points(cp, points))


def outline_strokes(cp: CreasePattern, points: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`outline_loops` as arrays, like :func:`crease_strokes`."""
    return _strokes(cp.edges[cp.assignment == "B"], _points(cp, points))


def split_strokes(points: np.ndarray, starts: np.ndarray) -> list[np.ndarray]:
    """The polylines of ``points`` that start at ``starts`` (ascending, the first 0), as views
    into ``points``: one slice each, not a copy (faster than ``np.split``, which also swaps
    axes twice per piece)."""
    bounds = np.append(starts, len(points)).tolist()
    return [points[a:b] for a, b in zip(bounds[:-1], bounds[1:])]


def stroke_segments(points: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """The segments (S, 2) complex of the polylines of ``points`` that start at ``starts``, in order."""
    keep = np.ones(max(len(points) - 1, 0), dtype=bool)
    keep[starts[1:] - 1] = False  # from the last point of one polyline to the first of the next
    return np.column_stack([points[:-1][keep], points[1:][keep]]) if len(keep) else np.zeros((0, 2), complex)


def vertex_points(cp: CreasePattern) -> np.ndarray:
    """The crease pattern's vertices as complex numbers (mm)."""
    return cp.vertices[:, 0] + 1j * cp.vertices[:, 1]


def _points(cp: CreasePattern, points: np.ndarray | None) -> np.ndarray:
    return vertex_points(cp) if points is None else points


def _strokes(edges: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_chains` as (points one polyline after another, where each starts)."""
    vertices, starts = _chain_vertices(edges, points)
    return points[vertices], starts


def _chains(edges: np.ndarray, points: np.ndarray) -> list[np.ndarray]:
    """:func:`_chain_vertices` as polylines, complex arrays of their points."""
    return split_strokes(*_strokes(edges, points))


def _chain_vertices(edges: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``edges`` (E, 2 indices into ``points``) drawn with as few pen lifts as a graph allows,
    going straight on through crossings.

    A connected set of edges with ``2k`` vertices of odd degree needs ``k`` strokes (one
    closed loop if ``k`` is 0), and that many suffice (Euler).  Hierholzer's algorithm
    finds them: an extra vertex joined to every odd vertex makes every degree even; the
    Euler circuits of that graph, cut where they pass the extra vertex, are the strokes.
    At every vertex the walk leaves by the edge :func:`_straight_pairs` pairs with the one
    it came in by, while that edge is unused: creases that cross are drawn through rather
    than turned at, and a plotter slows down or stops at every turn.  Where following the
    pairs alone walks every edge (they close no circuit), :func:`_trails` reads the strokes
    off at once; otherwise :func:`_circuit` walks, splicing the circuits in.  Closed loops
    repeat their first point.  Deterministic (otherwise neighbours in index order).  Returns
    the strokes' vertices one stroke after another and where each stroke starts.
    """
    count = len(points)
    odd = np.flatnonzero(np.bincount(edges.ravel(), minlength=count) % 2)
    extra = count
    pairs = np.concatenate([edges.reshape(-1, 2), np.column_stack([odd, np.full(len(odd), extra)])])
    # adjacency lists side by side (CSR): each vertex's neighbours in index order, then by edge;
    # slot k leaves vertex ends[order[k]] by edge order[k] // 2 (the edges' ends side by side,
    # so a stable sort by vertex and neighbour leaves an edge's ends in edge order: one key, and
    # the ends come nearly sorted, which a stable sort is quick at)
    # (each temporary is let go once used: a million edges make arrays of tens of megabytes)
    ends, others = pairs.ravel(), pairs[:, ::-1].ravel()
    order = np.argsort(ends * np.int64(count + 1) + others, kind="stable")
    at, to, ids = ends[order], others[order], order // 2
    del ends, others
    offsets = np.searchsorted(at, np.arange(count + 2))
    slot = np.empty_like(order)
    slot[order] = np.arange(len(order))
    arrive = slot[order ^ 1]  # the slot of the same edge at its other end
    del slot, order
    placed = np.append(points, 0)  # (the extra vertex anywhere: its edges have no direction)
    steps = np.where(to < extra, placed[to] - placed[at], 0)
    del placed
    lengths = np.abs(steps)
    unit = np.divide(steps, lengths, out=steps, where=lengths > 0)  # in place: a zero step stays zero
    del lengths
    partner = _straight_pairs(at, unit, to < extra, extra)
    del unit
    trails = _trails(at, to, arrive, partner, extra) if len(odd) else None  # (no odd vertex: all circuits)
    if trails is not None:
        return trails
    # (one more slot, after the last, is the one a walk "arrives" by at its start: no partner);
    # machine-int arrays, not lists: a list holds an int object per slot (a million edges: a gigabyte)
    state = (_ints(ids), _ints(arrive), _ints(np.append(partner, -1)), _ints(np.append(at, extra)),
             _ints(offsets[:-1]), _ints(offsets[1:]), bytearray(len(pairs)))
    walks = _circuit(extra, extra, *state) if len(odd) else []  # every component with odd vertices
    left = np.flatnonzero(np.frombuffer(state[-1], dtype=bool)[:len(edges)] == 0)  # closed components
    for start in np.unique(edges[left].min(axis=1)).tolist():
        walks += _circuit(start, extra, *state)
    sizes = np.fromiter(map(len, walks), dtype=np.intp, count=len(walks))
    return np.fromiter(chain.from_iterable(walks), dtype=np.intp, count=int(sizes.sum())), np.cumsum(sizes) - sizes


def _ints(values: np.ndarray) -> array:
    """``values`` as a Python array of machine integers (indexed like a list, 8 bytes an entry)."""
    return array("q", np.asarray(values, dtype=np.int64).tobytes())


def _trails(at: np.ndarray, to: np.ndarray, arrive: np.ndarray, partner: np.ndarray,
            extra: int) -> tuple[np.ndarray, np.ndarray] | None:
    """The strokes the pairs make by themselves, as their vertices one after another and
    where each starts, or None where the pairs also close circuits (which
    Hierholzer's walk must splice in).

    Leaving by slot ``s``, a walk comes in by ``arrive[s]`` and leaves by its partner; a
    stroke runs from a slot at the extra vertex to one into it.  Every slot finds its
    stroke and place in it by pointer jumping on the slot before it (list ranking, one
    doubling per round, on the slots not at their stroke's head yet); each stroke is found
    from both ends and kept from the lower.
    """
    size = len(at)
    head = at == extra
    pointer = np.where(head, np.arange(size), arrive[partner])  # the slot before; a head: itself
    rank = (~head).astype(np.intp)
    active = np.flatnonzero(~head[pointer])  # the slots whose pointer has yet to reach a head
    for _ in range(size.bit_length()):
        if not len(active):
            break
        before = pointer[active]
        rank[active] += rank[before]  # (each side read whole before it is written: one round at once)
        pointer[active] = pointer[before]
        active = active[~head[pointer[active]]]
    if len(active):
        return None
    last = np.flatnonzero(to == extra)
    kept = np.zeros(size, dtype=bool)
    kept[pointer[last]] = pointer[last] < arrive[last]
    slots = np.flatnonzero(kept[pointer] & ~head)
    slots = slots[np.lexsort((rank[slots], pointer[slots]))]
    return at[slots], np.flatnonzero(np.diff(pointer[slots], prepend=-1))


def _circuit(start: int, extra: int, edge: array, arrive: array, partner: array,
             vertex: array, cursor: array, stop: array, used: bytearray) -> list[list[int]]:
    """Hierholzer's Euler circuit from ``start`` over the unused edges, cut where it passes
    the ``extra`` vertex: the strokes, as lists of vertices (pieces of one vertex dropped).
    Slot lists as built in :func:`_chains`; marks the edges it walks used."""
    fake = len(arrive)
    vertex[fake] = start
    circuit, stack = [], [fake]  # the slots the walk arrived by
    while stack:  # extend the walk; at a dead end, emit the vertex and back up
        came = stack[-1]
        i = partner[came]
        while i >= 0 and not used[edge[i]]:  # straight on, as long as the pairs lead
            used[edge[i]] = True
            came = arrive[i]
            stack.append(came)
            i = partner[came]
        v = vertex[came]
        i, last = cursor[v], stop[v]
        while i < last and used[edge[i]]:
            i += 1
        cursor[v] = i
        if i == last:
            circuit.append(v)
            stack.pop()
        else:
            used[edge[i]] = True
            stack.append(arrive[i])
    walks, piece = [], []
    for v in circuit + [extra]:
        if v == extra:
            if len(piece) > 1:
                walks.append(piece)
            piece = []
        else:
            piece.append(v)
    return walks


def _straight_pairs(at: np.ndarray, unit: np.ndarray, real: np.ndarray, extra: int) -> np.ndarray:
    """Pair the edge ends (slots) at each vertex to go as straight on as possible.

    ``at`` is each slot's vertex (sorted), ``unit`` its direction away from the vertex
    (complex), ``real`` whether its edge is one of the graph's, not one to the ``extra``
    vertex, whose slots are left unpaired.  Greedy per vertex: the two free slots whose
    directions are most nearly opposite pair first (of equal pairs, the first in slot order);
    an edge to the extra vertex pairs last, so it takes the edge left over at an odd vertex.
    Vertices of ``k`` slots are worked out together, as rows of their ``k (k - 1) / 2`` pairs.
    Returns each slot's partner slot (-1 for none).
    """
    size = len(at)
    partner = np.full(size, -1, dtype=np.intp)
    starts = np.flatnonzero(np.diff(at, prepend=-1))  # each vertex's first slot, and its slots
    counts = np.diff(starts, append=size)
    counts[at[starts] == extra] = 0
    for k in np.unique(counts[counts > 1]).tolist():
        i, j = np.triu_indices(k, 1)  # the pairs of a vertex's slots, in slot order
        rows = max(1, CHUNK // len(i))
        firsts = starts[counts == k]
        for part in range(0, len(firsts), rows):  # in slices: the complex temporaries are 16 bytes a pair
            first = firsts[part:part + rows, None]
            a, b = first + i, first + j
            if k == 2:  # no choice to make
                cost = np.zeros((len(first), 1))
            else:
                cost = np.where(real[a] & real[b], (unit[a] * unit[b].conj()).real, 2.0)
            row = np.arange(len(first))
            for _ in range(k // 2):  # the best pair of free slots at every vertex; argmin: the first of equals
                best = np.argmin(cost, axis=1)
                partner[a[row, best]], partner[b[row, best]] = b[row, best], a[row, best]
                if k > 3:  # no pair with a slot just paired is free any more
                    taken = i[best, None], j[best, None]
                    cost[(i == taken[0]) | (i == taken[1]) | (j == taken[0]) | (j == taken[1])] = np.inf
    return partner


CHUNK = 1 << 20
"""Pairs costed at a time in :func:`_straight_pairs` (bounds its temporary arrays)."""


def dash_bound(segments: np.ndarray, pattern: tuple[float, ...], clearance: float) -> int:
    """At most how many dashes :func:`perforate` cuts ``segments`` (S, 2) into: counted before
    they are cut, so that a pattern too fine for the creases is refused up front."""
    usable = np.abs(segments[:, 1] - segments[:, 0]) - 2.0 * clearance
    return int(np.ceil(usable[usable > 0] / sum(pattern)).sum()) * (len(pattern) // 2)


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
