"""Greedy nearest-end stroke order over a whole layer, with batched KD-tree queries.

From where the pen is, draw next the stroke with an end nearest to it, entering at that end
(either way round), and repeat from the other end: the order vpype's ``linesort`` aims at,
without its cost.  vpype asks its KD-tree for 100 neighbours of the pen twice per stroke
through scipy's Python wrapper (15 µs apiece) and rebuilds it over every remaining line
whenever the pen's neighbourhood runs dry; on the 100,000 strokes of a 12.6 m roll that was
two thirds of an export.  Here ``cKDTree.query`` finds the :data:`NEIGHBOURS` nearest ends of
every stroke end at once, in C, once per layer (:class:`StrokeEnds`, shared by the walks from the
pen and from the goal; its tree also finds where stragglers may move); the walk then takes the
first of the pen's neighbours still undrawn (drawn ones are skipped, never deleted), most often
from a few kept in its exact order of choice.  Only when all of them are drawn does it
ask a second tree, over the ends still undrawn when it was built, rebuilt once half of those
are drawn.

The choice is exact: the nearest undrawn end by squared distance ``dx*dx + dy*dy``, ties to
the lowest end index (stroke ``i``'s first point is end ``2i``, its last ``2i + 1``).  The
trees only propose candidates; a candidate is taken when every end the tree left out is
farther by more than rounding (:data:`MARGIN`), so the order is that of the plain O(n²)
greedy walk, deterministic and with no state shared between threads.  :func:`nearest_order`
then moves the strokes the walk left behind, never adding travel.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

NEIGHBOURS = 12
"""Nearest ends looked up for every stroke end at once (at least 3: :meth:`StrokeEnds.meet`).  The
walk's choice does not depend on it, its speed does: fewer, and the walk asks its second tree
more often (30 µs each); more, and the query of every end costs more.  The roll's sort took
least CPU at 12 (0.80 s; 10: 0.85 s, 16: 0.88-0.95 s): 5,613 asks and 0.20 s of queries,
against 4,710 and 0.27 s at 16."""

PLACES = 16
"""Nearest ends of a straggler's two ends whose strokes :func:`_relocate` tries to put it beside
(part of the order: more find more places, at more cost)."""

FIRST = 4
"""Nearest other ends of each end kept in the exact order of the walk's choice (:class:`StrokeEnds`)."""

MARGIN = 1e-9
"""Relative margin by which the tree's distances (rounded differently) must separate a candidate
from the ends the tree did not return, for the choice to stand without a closer look."""


BLOCK = 1 << 16
"""Ends whose neighbours :class:`StrokeEnds` looks up and orders at a time (its working memory)."""


class StrokeEnds:
    """The ends of a layer's strokes (end ``2i``: stroke ``i``'s first point, ``2i + 1``: its last)
    and the :data:`NEIGHBOURS` nearest ends of each, by one ``cKDTree`` over them shared by every
    walk, by :func:`_relocate` (:meth:`near_strokes`) and by :meth:`meet`, asked :data:`BLOCK`
    ends at a time.  Flat arrays, read through ``memoryview`` in the walk: an item of one is a
    Python number at a fraction of the cost of a NumPy scalar or of a ``tolist``."""

    def __init__(self, starts: np.ndarray, ends: np.ndarray):
        from scipy.spatial import cKDTree  # vpype's line index is built on it

        self.points = np.column_stack([starts, ends]).ravel()
        self.xy = np.column_stack([self.points.real, self.points.imag])
        count = len(self.points)
        self.k, self.width = min(NEIGHBOURS, count), min(FIRST, NEIGHBOURS, count)
        kind = np.int32 if count < 2**31 else np.intp
        self.dist, self.index = np.empty((count, self.k)), np.empty((count, self.k), dtype=kind)
        self.first = np.empty((count, self.width), dtype=kind)
        self.apart = np.empty(count)  # by the tree, from each end to the nearest end of another stroke in its row
        self.tree = tree = cKDTree(self.xy) if count else None  # the walks' first second tree too
        for begin in range(0, count, BLOCK):
            block = slice(begin, begin + BLOCK)
            dist, index = tree.query(self.xy[block], k=self.k)
            dist, index = dist.reshape(-1, self.k), index.reshape(-1, self.k)
            self.dist[block], self.index[block] = dist, index
            own = (index >> 1) == (np.arange(begin, begin + len(index)) >> 1)[:, None]
            self.apart[block] = np.where(own, np.inf, dist).min(axis=1, initial=np.inf)
            self.first[block] = self._first(begin, index, dist, own)
        self.dist, self.index, self.first = self.dist.reshape(-1), self.index.reshape(-1), self.first.reshape(-1)

    def _first(self, begin: int, rows: np.ndarray, dist: np.ndarray, own: np.ndarray) -> np.ndarray:
        """For the ends from ``begin`` with neighbours ``rows`` (at tree distances ``dist``; ``own``:
        the ends of their own strokes), the :data:`FIRST` nearest ends of other strokes in the
        walk's order of choice (by ``dx*dx + dy*dy``, ties to the lowest end), each as far as its
        row shows it: -1 from the first one that an end beyond the row might precede (by
        :data:`MARGIN`).  Leaving by that end, the pen's next stroke is the first of them still
        undrawn, if no -1 comes before it: every end nearer than that one is drawn (its own
        stroke's other end too)."""
        at = self.xy[begin:begin + len(rows)]
        dx, dy = self.xy[rows, 0] - at[:, :1], self.xy[rows, 1] - at[:, 1:]
        key = np.where(own, np.inf, dx * dx + dy * dy)
        seen = dist * (1 + MARGIN) + 1e-12 < dist[:, -1:] if self.k < len(self.points) else np.isfinite(dist)
        chosen = np.lexsort((rows, key), axis=1)[:, :self.width]
        known = np.logical_and.accumulate(np.take_along_axis(seen & np.isfinite(key), chosen, axis=1), axis=1)
        return np.where(known, np.take_along_axis(rows, chosen, axis=1), -1)

    def meet(self, tolerance: float) -> bool:
        """Do ends of two different strokes lie within ``tolerance`` (or a rounding more)?  If two
        do, one of them is among the other's nearest ends, or so are two ends of other strokes
        as near (a stroke has two ends of its own)."""
        return bool(np.any(self.apart <= tolerance * (1 + MARGIN) + 1e-12))

    def near_strokes(self, stroke: int) -> list[int]:
        """The strokes of the :data:`PLACES` nearest ends of ``stroke``'s first end, then of its last
        (asked of the tree stroke by stroke: of the 16,700 strokes of the roll's three walks that
        might move, 719 come this far)."""
        index = self.tree.query(self.xy[2 * stroke:2 * stroke + 2], k=min(PLACES, len(self.points)))[1]
        return (index.reshape(-1) >> 1).tolist()


def greedy_order(starts: np.ndarray, ends: np.ndarray, pen: complex) -> tuple[np.ndarray, np.ndarray]:
    """The greedy nearest-end order of strokes from ``starts[i]`` to ``ends[i]`` (complex), from ``pen``.

    Returns the stroke indices in drawing order and, for each of them, whether it is drawn
    reversed (entered at its last point)."""
    return _greedy(StrokeEnds(starts, ends), pen)


def _greedy(table: StrokeEnds, pen: complex) -> tuple[np.ndarray, np.ndarray]:
    """:func:`greedy_order` over ``table``.  Leaving a stroke by an end, the pen takes the first still
    undrawn of that end's first ends in order (``table.first``) unless a -1 comes before it; else
    the first undrawn one of the end's row of neighbours unless another undrawn one ties with
    it within :data:`MARGIN` (then the exact nearest of those) or the row ends before the tie
    does; otherwise :class:`_Walk` searches the undrawn ends."""
    count = len(table.points) // 2
    walk = _Walk(table)
    undrawn, k, total = walk.undrawn, table.k, len(table.points)
    dist, index, first, width = memoryview(table.dist), memoryview(table.index), memoryview(table.first), table.width
    x, y = walk.x, walk.y
    entries = []
    at = -1  # the end the pen left by (-1: the pen is not on a stroke end)
    for step in range(count):
        entry = -1
        if at >= 0:
            j = at * width
            stop = j + width
            while j < stop:
                entry = first[j]
                if entry < 0 or undrawn[entry >> 1]:
                    break
                j += 1
            else:
                entry = -1
        if entry < 0 and at >= 0:  # the end's row of neighbours (the exact nearest of any tie)
            found = walk.pick(dist[at * k:at * k + k], index[at * k:at * k + k], complex(x[at], y[at]), total)
            entry = -1 if found is None else found
        if entry < 0:
            entry = walk.nearest(pen if at < 0 else complex(x[at], y[at]), total - 2 * step)
        undrawn[entry >> 1] = 0
        entries.append(entry)
        at = entry ^ 1
    entries = np.array(entries, dtype=np.intp)
    return entries >> 1, (entries & 1).astype(bool)


def nearest_order(starts: np.ndarray, ends: np.ndarray, pen: complex) -> tuple[np.ndarray, np.ndarray]:
    """:func:`greedy_order` with its stragglers moved: the order in which to draw the strokes
    from ``starts[i]`` to ``ends[i]`` from ``pen``, and which of them are drawn reversed.

    A greedy walk leaves strokes behind that it must come back for across the sheet (on the
    12.6 m roll, one valley at the far end it started from: a 12.5 m jump).  Each stroke that
    saves more than the walk's mean jump by leaving its place (:func:`_relocate`, most saving
    first) is moved, either way round, between two strokes that have an end among the
    :data:`PLACES` nearest ends of either of its own, where that costs least, if that costs
    less than it saves: the result never travels more than the greedy walk."""
    return nearest_orders(StrokeEnds(starts, ends), [pen])[0]


def nearest_orders(table: StrokeEnds, pens: list[complex]) -> list[tuple[np.ndarray, np.ndarray]]:
    """:func:`nearest_order` of the strokes of ``table`` from each of ``pens``."""
    out = []
    for pen in pens:
        order, flipped = _greedy(table, pen)
        out.append((order, flipped) if len(order) < 3 else _relocate(order, flipped, table, pen))
    return out


def _relocate(order: np.ndarray, flipped: np.ndarray, table: StrokeEnds,
              pen: complex) -> tuple[np.ndarray, np.ndarray]:
    """See :func:`nearest_order`: the strokes in a linked list (``head``: the pen), each moved once."""
    count = len(order)
    points = table.points
    x, y = points.real.tolist() + [pen.real], points.imag.tolist() + [pen.imag]
    head = count
    turned = np.zeros(count + 1, dtype=bool)
    turned[order] = flipped
    turned = turned.tolist()
    chain = np.concatenate([[head], order])
    after = np.full(count + 1, -1, dtype=np.intp)  # the next stroke (-1: none)
    before = np.full(count + 1, -1, dtype=np.intp)
    after[chain[:-1]], before[chain[1:]] = chain[1:], chain[:-1]
    after, before = after.tolist(), before.tolist()

    def jump(a: int, b: int) -> float:  # from the end of stroke a (head: the pen) into stroke b
        if b < 0:
            return 0.0
        out = 2 * head if a == head else 2 * a + (not turned[a])
        into = 2 * b + turned[b]
        return math.hypot(x[out] - x[into], y[out] - y[into])

    into = 2 * order + flipped
    left = np.concatenate([[pen], points[into[:-1] ^ 1]])  # where the pen is before each stroke
    steps = np.hypot((points[into] - left).real, (points[into] - left).imag)
    saves = steps + np.append(steps[1:], 0)  # leaving: the jumps in and out (the bridge is subtracted below)
    mean = float(steps.mean())
    order = order.tolist()
    for stroke in np.argsort(-saves, kind="stable").tolist():
        if saves[stroke] <= mean:
            break
        stroke = order[stroke]
        a, b = before[stroke], after[stroke]
        gain = jump(a, stroke) + jump(stroke, b) - jump(a, b)
        if gain <= 0:
            continue
        after[a] = b
        if b >= 0:
            before[b] = a
        best = (gain, a, turned[stroke])
        first, last = 2 * stroke, 2 * stroke + 1
        for other in set(table.near_strokes(stroke)) - {stroke}:
            for place in (other, before[other]):
                if place < 0:
                    continue
                # jump(place, stroke) + jump(stroke, nxt) - jump(place, nxt), the stroke either way
                # round, written out: a call per jump was half the time of the moves
                out = 2 * head if place == head else 2 * place + (not turned[place])
                px, py = x[out], y[out]
                nxt = after[place]
                if nxt < 0:
                    costs = (math.hypot(px - x[first], py - y[first]), math.hypot(px - x[last], py - y[last]))
                else:
                    into = 2 * nxt + turned[nxt]
                    nx, ny = x[into], y[into]
                    bridge = math.hypot(px - nx, py - ny)
                    costs = (math.hypot(px - x[first], py - y[first]) + math.hypot(x[last] - nx, y[last] - ny) - bridge,
                             math.hypot(px - x[last], py - y[last]) + math.hypot(x[first] - nx, y[first] - ny) - bridge)
                for turn, cost in enumerate(costs):
                    if cost < best[0] - 1e-9:
                        best = (cost, place, bool(turn))
        _, place, turned[stroke] = best
        after[stroke], before[stroke] = after[place], place
        if after[place] >= 0:
            before[after[place]] = stroke
        after[place] = stroke
    out = []
    at = after[head]
    while at >= 0:
        out.append(at)
        at = after[at]
    result = np.array(out, dtype=np.intp)
    return result, np.array(turned, dtype=bool)[result]


class _Walk:
    """The undrawn strokes (by stroke), and the nearest undrawn end to a point by a second tree."""

    def __init__(self, table: StrokeEnds):
        self.xy = xy = table.xy
        self.x, self.y = memoryview(np.ascontiguousarray(xy[:, 0])), memoryview(np.ascontiguousarray(xy[:, 1]))
        self.undrawn = bytearray(b"\x01") * (len(xy) // 2)
        self.tree = table.tree  # over the ends undrawn when it was built: ``self.ids`` (first: the table's, all)
        self.ids = np.arange(len(xy))

    def nearest(self, pen: complex, left: int) -> int:
        """The nearest undrawn end to ``pen`` (of ``left`` undrawn ends) by the second tree, asked for
        twice as many ends until it answers."""
        from scipy.spatial import cKDTree

        if 2 * left < len(self.ids):
            alive = np.repeat(np.frombuffer(bytes(self.undrawn), dtype=np.uint8).astype(bool), 2)
            self.ids = np.flatnonzero(alive)
            self.tree = cKDTree(self.xy[self.ids])
        k = min(2 * NEIGHBOURS, len(self.ids))
        while True:
            dist, index = self.tree.query((pen.real, pen.imag), k=k)
            found = self.pick(np.atleast_1d(dist).tolist(), self.ids[np.atleast_1d(index)].tolist(), pen,
                               len(self.ids))
            if found is not None:
                return found
            k = min(2 * k, len(self.ids))

    def pick(self, dist: Sequence[float], index: Sequence[int], pen: complex, total: int) -> int | None:
        """The nearest undrawn end among the nearest ``index`` (at tree distances ``dist``, ascending)
        of ``total`` ends, or None when the ends left out might be as near."""
        undrawn, x, y = self.undrawn, self.x, self.y
        for first, end in enumerate(index):
            if undrawn[end >> 1]:
                break
        else:
            return None
        bound = dist[first] * (1 + MARGIN) + 1e-12
        best = None
        for tree_distance, end in zip(dist[first:], index[first:]):
            if tree_distance > bound:
                break
            if undrawn[end >> 1]:
                dx, dy = x[end] - pen.real, y[end] - pen.imag
                key = (dx * dx + dy * dy, end)
                if best is None or key < best:
                    best = key
        else:
            if len(index) < total:  # the tie may go on among the ends not returned
                return None
        return best[1]
