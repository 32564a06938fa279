"""Pen-up travel optimization, layer by layer, on vpype's data model and operations.

Within each layer: vpype's ``linemerge`` (join lines whose ends meet; skipped when no two
ends are that close, since scoring has chained the creases already), a greedy nearest-end
sort of the whole layer (:mod:`foldfab.fabrication.sort`; with ``two-opt``, then vpype's
``linesort --two-opt`` window by window), vpype's ``linesimplify`` within the device's resolution,
closed outlines relooped to start where the pen arrives, and of the sorted order
and its reverse the one that enters and leaves the layer by less travel (its last
line turned round if it then ends nearer the next layer or the park position).  Layers
are never reordered; at a pause the pen parks, so the layer after it is sorted from the
park position.  :func:`travel` measures pen-up travel of a plan the way the plotter moves:
from the park position, within and between layers (all passes), to the park position and
back at every pause, and home.
"""

from __future__ import annotations

import itertools

import numpy as np

from foldfab.fabrication.plan import Pass, Pause, PlotPlan, collection, device_steps

METHODS = ("none", "greedy", "two-opt")


def optimize_plan(plan: PlotPlan, method: str, resolution: float, start: complex = 0j,
                  keep_vertices: frozenset[str] = frozenset(), tool_changer: bool = True) -> PlotPlan:
    """A copy of ``plan`` whose layers are merged (vpype), sorted and simplified (vpype).

    ``resolution`` (mm) bounds how far merging and simplification may move a point;
    ``start`` is where the pen is before the first layer and after every pause (the
    device's park position); layers named in ``keep_vertices`` are not simplified (their
    vertices matter, e.g. crease ends that perforation must spare); ``tool_changer`` false
    means the device also stops to change tools (:func:`foldfab.fabrication.plan.device_steps`).
    """
    if method == "none":
        return plan
    two_opt = method == "two-opt"
    steps = [step for _, step in device_steps(plan, tool_changer)]
    again = any(isinstance(step, Pass) and 1 < len(plan.document.layers[step.layer_id]) <= TWO_OPT_LINES
                for step in steps)
    # each layer's sorts by pen, kept for the second plan (which often starts a layer where the first did)
    cache: dict | None = {} if again else None
    best = _optimized(plan, steps, two_opt, resolution, start, keep_vertices, cache, mixed=True)
    if not again:
        return best
    # Layer by layer, the order that arrives and leaves by least may leave the next layer a worse
    # start (the star's valleys: 1 mm less, its mountains then 44 mm more): vpype's orders alone,
    # as before foldfab had its own sort, make the other plan, and the one that travels less wins.
    before = _optimized(plan, steps, two_opt, resolution, start, keep_vertices, cache, mixed=False)
    return min((best, before), key=lambda p: travel(p, start, tool_changer)["total"])


def _optimized(plan: PlotPlan, steps: list, two_opt: bool, resolution: float, start: complex,
               keep_vertices: frozenset[str], cache: dict | None, mixed: bool) -> PlotPlan:
    """:func:`optimize_plan` of ``plan`` as the device runs it (``steps``), each layer in the best of
    :func:`_ours` and, on a layer of at most :data:`TWO_OPT_LINES` lines, :func:`_theirs` (``mixed``
    false: :func:`_theirs` alone there; ``cache`` keeps both by layer and pen, computed once; None:
    nothing is kept past its layer)."""
    forget = cache is None
    cache = {} if cache is None else cache
    doc = plan.document.clone()  # metadata only: layers are added below, in plan order
    pen = start
    # what the pen meets, in order: a layer to draw, or a pause (where the device parks it)
    meets = [step if isinstance(step, Pause) else plan.document.layers[step.layer_id] for step in steps]
    for index, step in enumerate(steps):
        if isinstance(step, Pause):
            pen = start
            continue
        lines = plan.document.layers[step.layer_id]
        if ("lines", index) not in cache:
            cache["lines", index] = _merged(lines.lines, resolution)
        result, loops = cache["lines", index][0::2]
        onward = _onward(meets[index + 1:], start, resolution)
        orders = []
        if 1 < len(result) <= TWO_OPT_LINES:
            if ("theirs", index, pen) not in cache:
                cache["theirs", index, pen] = _theirs(result, two_opt, pen)
            orders.append(cache["theirs", index, pen])
        if mixed or not orders:
            if ("ours", index, pen) not in cache:
                cache["ours", index, pen] = _ours(result, two_opt, pen, onward.goal(), cache["lines", index][1])
            orders[:0] = cache["ours", index, pen]
        cache["lines", index] = result, None, loops  # a million strokes' table is 200 MB: one layer's at a time
        result = min(_candidates(orders, pen, resolution, onward, loops), key=lambda c: _entry_exit(c, pen, onward))
        if isinstance(result, _Walked):
            result = result.lines()
        if step.name not in keep_vertices:  # last: simplifying keeps the ends of every line
            result = _simplify(result, resolution / 2)
        if forget:
            cache.clear()
        doc.layers.setdefault(step.layer_id, collection([])).lines.extend(result)  # not copied, as doc.add would
        doc.layers[step.layer_id].metadata.update(lines.metadata)
        if result:
            pen = result[-1][-1]
    return PlotPlan(doc, list(plan.steps), plan.sheet)


def _merged(lines: list[np.ndarray], tolerance: float):
    """``lines`` joined where their ends meet (vpype's ``linemerge``), the table of their ends
    (:class:`foldfab.fabrication.sort.StrokeEnds`, for the sort) and whether any is closed
    (:func:`_reloop` has work).  vpype is asked only when ends of
    two lines lie within ``tolerance``: scoring has chained every join at a shared vertex already,
    and on a layer of 50,000 lines vpype takes seconds to find nothing to merge."""
    from foldfab.fabrication.sort import StrokeEnds

    lines = [line for line in lines if len(line)]
    ends = _line_ends(lines)
    table = StrokeEnds(*ends)
    if table.meet(tolerance):
        merged = _collection(lines)
        merged.merge(tolerance=tolerance, flip=True)
        lines = [line for line in merged.lines if len(line)]
        ends = _line_ends(lines)
        table = StrokeEnds(*ends)
    return lines, table, bool(_closed_all(lines, tolerance, *ends).any())


def _collection(lines: list[np.ndarray]):
    """``lines`` as a vpype ``LineCollection`` of their own (vpype's operations change it in place)."""
    import vpype as vp

    return vp.LineCollection(lines)


def _vpype_operation(name: str):
    """The function behind vpype's layer command ``name`` (``linesort``, ``linesimplify``),
    called on a ``LineCollection`` directly.

    Never through ``vpype_cli.execute``: a pipeline runs in vpype's one global command state,
    so two fabrications in parallel threads (the studio, the queue's workers) read each other's
    lines.  The command's own function takes a collection and returns one, and touches no
    shared state; vpype keeps it as the ``__wrapped__`` of the command's callback."""
    from vpype_cli import operations

    return getattr(operations, name).callback.__wrapped__


def _ours(lines: list[np.ndarray], two_opt: bool, pen: complex, goal: complex | None,
          table=None) -> list[_Walked | list[np.ndarray]]:
    """foldfab's orders of ``lines`` from ``pen``, each line either way round: the greedy
    nearest-end order over the whole layer with its stragglers moved
    (:func:`foldfab.fabrication.sort.nearest_order`), and when the pen should end near ``goal``
    (the park position, or the best way into a closed outline on the way there) the same order
    from ``goal`` backwards; each, with ``two_opt``, improved window by window (:func:`_two_opt`).
    A greedy walk depends much on where it starts: the roll's mountains, entered where its
    valleys end, end 12 m from the park position; walked from there and drawn backwards,
    they end beside it.  ``table``: the ends of ``lines`` (:class:`foldfab.fabrication.sort.StrokeEnds`)
    when already found.  Orders by index (:class:`_Walked`), as lists of lines with ``two_opt``."""
    from foldfab.fabrication.sort import StrokeEnds, nearest_orders

    table = table or StrokeEnds(*_line_ends(lines))
    begins = [pen] if goal is None or len(lines) < 2 else [pen, goal]
    ours: list[_Walked | list[np.ndarray]] = []
    for begin, (order, flipped) in zip(begins, nearest_orders(table, begins)):
        walked = _Walked(lines, table.points, order, flipped)
        if begin is not pen:
            walked = walked.backwards()
        ours.append(_two_opt(walked.lines(), pen) if two_opt else walked)
    return ours


class _Walked:
    """A layer's ``lines`` in a drawing order, by index: line ``order[i]``, backwards where
    ``flipped[i]`` (``ends``: line ``i``'s first point at ``2i``, its last at ``2i + 1``).  On
    a layer of 50,000 lines, a candidate order as a list costs 50,000 views and their
    concatenation to measure; by index it is two arrays, and only the order chosen is made
    a list."""

    def __init__(self, lines: list[np.ndarray], ends: np.ndarray, order: np.ndarray, flipped: np.ndarray):
        self.source, self.ends, self.order, self.flipped = lines, ends, order, flipped

    def lines(self) -> list[np.ndarray]:
        lines = self.source
        return [lines[i][::-1] if turn else lines[i] for i, turn in zip(self.order.tolist(), self.flipped.tolist())]

    def backwards(self) -> _Walked:
        """The same lines drawn in the opposite order and direction (the same inner travel)."""
        return _Walked(self.source, self.ends, self.order[::-1], ~self.flipped[::-1])

    def firsts_and_lasts(self) -> tuple[np.ndarray, np.ndarray]:
        """The first and last points of each line as drawn, in order (:func:`_line_ends`)."""
        entry = 2 * self.order + self.flipped
        return self.ends[entry], self.ends[entry ^ 1]

    def end_towards(self, pen: complex, onward: _Onward) -> _Walked:
        """:func:`_end_towards` (from the last two lines' ends alone)."""
        entry = 2 * self.order[-2:] + self.flipped[-2:]
        if not len(entry) or not _turn_last(self.ends[entry[0] ^ 1] if len(entry) > 1 else pen,
                                            self.ends[entry[-1]], self.ends[entry[-1] ^ 1], onward):
            return self
        flipped = self.flipped.copy()
        flipped[-1] = not flipped[-1]
        return _Walked(self.source, self.ends, self.order, flipped)


def _candidates(orders: list[_Walked | list[np.ndarray]], pen: complex, resolution: float, onward: _Onward,
                loops: bool):
    """Each of ``orders`` and the same backwards (each line reversed: the same inner travel),
    closed lines relooped (``loops``, :func:`_reloop`) and the last line turned towards ``onward``
    (:func:`_end_towards`); made one at a time, since on a million strokes a candidate's list of
    lines is 100 MB."""
    for ordered in orders:
        if isinstance(ordered, _Walked):
            if not loops:
                yield ordered.end_towards(pen, onward)
                yield ordered.backwards().end_towards(pen, onward)
                continue
            ordered = ordered.lines()
        for order in (ordered, [line[::-1] for line in ordered[::-1]]):
            yield _end_towards(_reloop(order, pen, resolution, onward) if loops else order, pen, onward)


def _theirs(lines: list[np.ndarray], two_opt: bool, pen: complex) -> list[np.ndarray]:
    """vpype's ``linesort`` (``--two-opt``) of ``lines`` from the line nearest ``pen``, foldfab's
    order before it had its own sort.  A greedy walk depends on how ties are broken too, and on
    symmetric crease patterns full of them, and in two-opt's local optima, vpype's is at times
    the better (the star's mountains, 285 mm against 358 mm; the lantern's two-opt outlines,
    1,430 mm against 1,769 mm); it costs little on a small layer and seconds on a large one."""
    return _vpype_operation("linesort")(_collection(_nearest_first(lines, pen)), no_flip=False, two_opt=two_opt,
                                        passes=SORT_PASSES).lines


TWO_OPT_LINES = 2000
"""Lines per window of :func:`_two_opt` (vpype's two-opt takes time quadratic in the lines it is
given), and most lines of a layer that :func:`_theirs` also sorts."""

SORT_PASSES = 250
"""Passes of vpype's two-opt sort at most (the default of its ``linesort --passes``)."""


def _two_opt(lines: list[np.ndarray], pen: complex) -> list[np.ndarray]:
    """``lines`` (in drawing order from ``pen``) improved by vpype's ``linesort --two-opt``, run on
    consecutive windows of :data:`TWO_OPT_LINES` lines, each from where the pen left the one
    before.  A window's new order is kept only if the way into it, through it and on to the
    next window's first line is shorter than before, so the whole never travels more than
    ``lines`` (one two-opt over a 50,000-line layer had not finished after 15 minutes)."""
    linesort = _vpype_operation("linesort")
    out: list[np.ndarray] = []
    for begin in range(0, len(lines), TWO_OPT_LINES):
        window = lines[begin:begin + TWO_OPT_LINES]
        after = _Onward(np.array([lines[begin + TWO_OPT_LINES][0]])) if begin + TWO_OPT_LINES < len(lines) else None
        if len(window) > 1:
            improved = linesort(_collection(window), no_flip=False, two_opt=True, passes=SORT_PASSES).lines
            if _entry_exit(improved, pen, after) < _entry_exit(window, pen, after):
                window = improved
        out.extend(window)
        pen = out[-1][-1]
    return out


def _nearest_first(lines: list[np.ndarray], pen: complex) -> list[np.ndarray]:
    """``lines`` with the one whose end is nearest ``pen`` moved first (and turned to start there)."""
    starts, ends = _line_ends(lines)
    dist = np.minimum(np.abs(starts - pen), np.abs(ends - pen))
    i = int(np.argmin(dist))
    first = lines[i] if abs(starts[i] - pen) <= abs(ends[i] - pen) else lines[i][::-1]
    return [first, *lines[:i], *lines[i + 1:]]


def _simplify(lines: list[np.ndarray], tolerance: float) -> list[np.ndarray]:
    """vpype's ``linesimplify`` on the lines it could shorten (three points or more), the
    others left as they are in place: a layer of single crease segments is not sent through
    shapely and back for nothing (1 s for 50,000 lines)."""
    whole = _kept_whole(lines, tolerance)
    bent = [i for i, line in enumerate(lines) if len(line) > 2 and not whole[i]]
    if not bent:
        return lines
    out = list(lines)
    # shapely simplifies each line on its own and keeps every one (a collapsed one as two points)
    simplified = _vpype_operation("linesimplify")(_collection([lines[i] for i in bent]), tolerance)
    for i, line in zip(bent, simplified.lines, strict=True):
        out[i] = line
    return out


KEPT_WHOLE_POINTS = 6
"""Longest lines that :func:`_kept_whole` checks (it tests every point against every chord over it)."""


def _kept_whole(lines: list[np.ndarray], tolerance: float) -> np.ndarray:
    """Which lines Douglas-Peucker surely leaves as they are, so that simplifying them is skipped.

    It does when every inner point lies farther than ``tolerance`` from every chord between
    a point before it and a point after it: the algorithm only ever measures a point against
    such a chord (as a segment, never nearer than its line), and keeps a point farther than
    ``tolerance``.  A margin absorbs rounding; lines longer than :data:`KEPT_WHOLE_POINTS`
    points, and chords of zero length, are left for vpype to judge.  The roll's 50,000 zigzag
    lines of four points skip shapely this way (0.5 s).
    """
    whole = np.zeros(len(lines), dtype=bool)
    sizes = np.array([len(line) for line in lines])
    for size in range(3, KEPT_WHOLE_POINTS + 1):
        chosen = np.flatnonzero(sizes == size)
        if not len(chosen):
            continue
        points = np.array([lines[i] for i in chosen])
        far = np.ones(len(chosen), dtype=bool)
        for a, i, b in itertools.combinations(range(size), 3):
            chord = points[:, b] - points[:, a]
            length = np.abs(chord)
            cross = np.abs((np.conj(chord) * (points[:, i] - points[:, a])).imag)
            far &= (length > 0) & (cross > (1.001 * tolerance + 1e-9) * length)
        whole[chosen] = far
    return whole


def _entries(lines, tolerance: float) -> np.ndarray:
    """Where the pen can begin drawing ``lines``: the ends of open lines, any vertex of a
    closed one (it is relooped to start there)."""
    starts, ends = _line_ends(lines)
    closed = _closed_all(lines, tolerance, starts, ends)
    if not closed.any():
        return np.column_stack([starts, ends]).ravel()
    return np.concatenate([line if shut else line[[0, -1]] for line, shut in zip(lines, closed.tolist())])


class _Onward:
    """The pen-up travel still to come once the pen leaves a layer, by where it leaves: the
    shortest way to one of ``targets`` plus that target's ``extra`` (none: the nearest)."""

    def __init__(self, targets: np.ndarray, extra: np.ndarray | None = None):
        from scipy.spatial import cKDTree  # vpype's line index is built on it

        self.targets, self.extra = targets, extra
        self.index = cKDTree(np.column_stack([targets.real, targets.imag])) if extra is None else None

    def costs(self, points: np.ndarray) -> np.ndarray:
        if self.index is not None:
            return self.index.query(np.column_stack([points.real, points.imag]))[0]
        return np.min(np.abs(points[:, None] - self.targets[None, :]) + self.extra, axis=1)

    def cost(self, point: complex) -> float:
        return float(self.costs(np.array([point]))[0])

    def goal(self) -> complex | None:
        """Where best to leave for what follows, when that is one point or a closed loop."""
        if self.extra is not None:
            return complex(self.targets[int(np.argmin(self.extra))])
        return complex(self.targets[0]) if len(self.targets) == 1 else None


def _onward(later: list, park: complex, tolerance: float) -> _Onward:
    """What follows a layer that the layers and pauses ``later`` follow: the nearest entry
    of the next layer with lines; through a layer that is one closed loop, which the pen
    leaves where it came in, on to what follows that; the park position at a pause and
    after the last layer."""
    onward = _Onward(np.array([park]))
    for layer in reversed(later):
        if isinstance(layer, Pause):
            onward = _Onward(np.array([park]))
            continue
        if not len(layer):
            continue
        lines = layer.lines
        if len(lines) == 1 and _closed(lines[0], tolerance):
            loop = lines[0][:-1]
            onward = _Onward(loop, onward.costs(loop))
        else:
            onward = _Onward(_entries(lines, tolerance))
    return onward


def _closed(line: np.ndarray, tolerance: float) -> bool:
    """A loop :func:`_reloop` may start anywhere."""
    return len(line) > 3 and abs(line[0] - line[-1]) <= tolerance


def _closed_all(lines: list[np.ndarray], tolerance: float, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """:func:`_closed` of each of ``lines`` (first points ``starts``, last ``ends``) at once."""
    sizes = np.fromiter(map(len, lines), dtype=np.intp, count=len(lines))
    return (sizes > 3) & (np.abs(starts - ends) <= tolerance)


def _line_ends(lines: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The first and the last points of ``lines`` (at least one point each), as two arrays: through
    one concatenation, since indexing 50,000 lines one by one costs more than copying them."""
    if not len(lines):
        return np.zeros(0, dtype=complex), np.zeros(0, dtype=complex)
    stops = np.cumsum(np.fromiter(map(len, lines), dtype=np.intp, count=len(lines)))
    points = np.concatenate(lines)
    return points[np.append(0, stops[:-1])], points[stops - 1]


def _entry_exit(lines: list[np.ndarray] | _Walked, pen: complex, onward: _Onward | None) -> float:
    """Travel from ``pen`` into ``lines``, inside them (reloop and the last line's turn change
    it) and from their end on (``onward``; None: nowhere)."""
    starts, ends = lines.firsts_and_lasts() if isinstance(lines, _Walked) else _line_ends(lines)
    if not len(starts):
        return 0.0
    inside = float(np.abs(starts[1:] - ends[:-1]).sum())
    return abs(starts[0] - pen) + inside + (0.0 if onward is None else onward.cost(ends[-1]))


def _end_towards(lines: list[np.ndarray], pen: complex, onward: _Onward) -> list[np.ndarray]:
    """Reverse the layer's last line if the pen then gets there and on (``onward``: the next
    layer, or the park position) by less travel."""
    if lines and _turn_last(lines[-2][-1] if len(lines) > 1 else pen, lines[-1][0], lines[-1][-1], onward):
        return [*lines[:-1], lines[-1][::-1]]
    return lines


def _turn_last(before: complex, first: complex, last: complex, onward: _Onward) -> bool:
    """Is a layer's last line (from ``first`` to ``last``, an open one), entered from ``before``,
    better drawn backwards, for the way in and on (``onward``)?"""
    return first != last and abs(before - last) + onward.cost(first) < abs(before - first) + onward.cost(last)


def _reloop(lines: list[np.ndarray], pen: complex, tolerance: float, onward: _Onward) -> list[np.ndarray]:
    """Start every closed line at the vertex nearest to where the pen comes from; the layer's
    last line, if closed, where coming in and going on (``onward``) add up to least."""
    import vpype as vp

    closed = np.flatnonzero(_closed_all(lines, tolerance, *_line_ends(lines)))
    if not len(closed):
        return lines
    out = list(lines)
    for index in closed.tolist():
        line = lines[index]
        cost = np.abs(line[:-1] - (out[index - 1][-1] if index else pen))
        if index == len(lines) - 1:
            cost += onward.costs(line[:-1])
        out[index] = vp.reloop(line, int(np.argmin(cost)))
    return out


def travel(plan: PlotPlan, park: complex = 0j, tool_changer: bool = True) -> dict:
    """Pen-up travel in mm: per layer (inside it, all passes), between layers, to the park
    position and back at pauses (``tool_changer`` false: tool changes too, see
    :func:`foldfab.fabrication.plan.device_steps`) and from and to ``park`` at the start and end."""
    per_layer: dict[str, float] = {}
    between = 0.0
    pen, parked = park, True
    first = True
    for _, step in device_steps(plan, tool_changer):
        if isinstance(step, Pause):
            per_layer["at pauses"] = per_layer.get("at pauses", 0.0) + abs(pen - park)
            pen, parked = park, True
            continue
        lines = plan.document.layers.get(step.layer_id)
        if lines is None or len(lines) == 0:
            continue
        inside = float(lines.pen_up_length()[0])
        loop_back = abs(lines.lines[-1][-1] - lines.lines[0][0])
        arrive = abs(lines.lines[0][0] - pen)
        if first:
            per_layer["from park"] = arrive
            first = False
        elif parked:
            per_layer["at pauses"] += arrive
        else:
            between += arrive
        per_layer[step.name] = per_layer.get(step.name, 0.0) + inside * step.tool.passes + loop_back * (step.tool.passes - 1)
        pen, parked = lines.lines[-1][-1], False
    per_layer["between layers"] = between
    per_layer["to park"] = abs(pen - park)
    total = sum(per_layer.values())
    return {"layers": per_layer, "total": total}
