"""Pen-up travel optimization with vpype's own operations, layer by layer.

Within each layer: ``linemerge`` (join lines whose ends meet; skipped when no two
ends are that close, since scoring has chained the creases already), ``linesort``
(greedy, or with ``--two-opt``), ``linesimplify`` within the device's resolution,
closed outlines relooped to start where the pen arrives, and of the sorted order
and its reverse the one that enters and leaves the layer by less travel (its last
line turned round if it then ends nearer the next layer or the park position).  Layers
are never reordered.  :func:`travel` measures pen-up travel of a plan the way the plotter
moves: from the park position, within and between layers (all passes), and back.
"""

from __future__ import annotations

import numpy as np

from foldfab.plan import Pass, PlotPlan

METHODS = ("none", "greedy", "two-opt")


def optimize_plan(plan: PlotPlan, method: str, resolution: float, start: complex = 0j,
                  keep_vertices: frozenset[str] = frozenset()) -> PlotPlan:
    """A copy of ``plan`` whose layers are merged, sorted and simplified by vpype.

    ``resolution`` (mm) bounds how far merging and simplification may move a point;
    ``start`` is where the pen is before the first layer (the device's park position);
    layers named in ``keep_vertices`` are not simplified (their vertices matter, e.g.
    crease ends that perforation must spare).
    """
    import vpype as vp
    import vpype_cli

    if method == "none":
        return plan
    sort = "linesort --two-opt" if method == "two-opt" else "linesort"
    doc = plan.document.clone()  # metadata only: layers are added below, in plan order
    pen = start
    passes = [step for step in plan.steps if isinstance(step, Pass)]
    for index, step in enumerate(passes):
        lines = plan.document.layers[step.layer_id]
        single = vp.Document()
        single.add(vp.LineCollection(lines.lines), 1)
        # vpype's linesort starts from the layer's first line: put the one nearest the pen first.
        simplify = "" if step.name in keep_vertices else f" linesimplify --tolerance {resolution / 2}"
        merge = f"linemerge --tolerance {resolution} " if _ends_meet(lines, resolution) else ""
        out = vpype_cli.execute(f"{merge}{sort}{simplify}", _nearest_first(single, pen))
        result = out.layers.get(1, vp.LineCollection())
        later = [plan.document.layers[p.layer_id] for p in passes[index + 1:]]
        following = next((_entries(layer, resolution) for layer in later if len(layer)), np.array([start]))
        # The sorted order backwards (each line reversed) has the same inner travel: take the
        # direction that arrives and leaves by less.
        candidates = [_end_towards(_reloop(order, pen, resolution), pen, following)
                      for order in (result, vp.LineCollection([line[::-1] for line in result.lines[::-1]]))]
        result = min(candidates, key=lambda c: _entry_exit(c, pen, following))
        for name, value in lines.metadata.items():
            result.set_property(name, value)
        doc.add(result, step.layer_id, with_metadata=True)
        if len(result):
            pen = result.lines[-1][-1]
    return PlotPlan(doc, list(plan.steps), plan.sheet)


def _ends_meet(lines, tolerance: float) -> bool:
    """Do ends of two different lines lie within ``tolerance``?  If not, vpype's ``linemerge``
    would merge nothing (scoring already chained every join at a shared vertex), and on a
    layer of 50,000 lines it takes seconds to find that out."""
    from scipy.spatial import cKDTree  # vpype's line index is built on it

    if len(lines) < 2:
        return False
    ends = np.array([(line[0], line[-1]) for line in lines]).ravel()
    pairs = cKDTree(np.column_stack([ends.real, ends.imag])).query_pairs(tolerance, output_type="ndarray")
    return bool(np.any(pairs[:, 0] // 2 != pairs[:, 1] // 2))


def _nearest_first(doc, pen: complex):
    lines = doc.layers[1]
    if len(lines) > 1:
        starts = np.array([line[0] for line in lines])
        ends = np.array([line[-1] for line in lines])
        dist = np.minimum(np.abs(starts - pen), np.abs(ends - pen))
        i = int(np.argmin(dist))
        first = lines.lines[i] if abs(starts[i] - pen) <= abs(ends[i] - pen) else lines.lines[i][::-1]
        rest = [line for k, line in enumerate(lines.lines) if k != i]
        lines.lines[:] = [first, *rest]
    return doc


def _entries(lines, tolerance: float) -> np.ndarray:
    """Where the pen can begin drawing ``lines``: the ends of open lines, any vertex of a
    closed one (it is relooped to start there)."""
    return np.concatenate([line if abs(line[0] - line[-1]) <= tolerance else line[[0, -1]]
                           for line in lines])


def _entry_exit(lines, pen: complex, following: np.ndarray) -> float:
    """Travel from ``pen`` into ``lines`` and from their end on to the nearest of ``following``,
    plus the travel inside (reloop and the last line's turn change it)."""
    if not len(lines):
        return 0.0
    inside = float(lines.pen_up_length()[0])
    return abs(lines.lines[0][0] - pen) + inside + float(np.min(np.abs(following - lines.lines[-1][-1])))


def _end_towards(lines, pen: complex, following: np.ndarray):
    """Reverse the layer's last line if the pen then gets there and on to the nearest of
    ``following`` (the next layer's line ends, or the park position) by less travel."""
    import vpype as vp

    if not len(lines) or lines.lines[-1][0] == lines.lines[-1][-1]:
        return lines
    last = lines.lines[-1]
    before = lines.lines[-2][-1] if len(lines) > 1 else pen
    onward = lambda point: float(np.min(np.abs(following - point)))  # noqa: E731
    if abs(before - last[-1]) + onward(last[0]) < abs(before - last[0]) + onward(last[-1]):
        return vp.LineCollection([*lines.lines[:-1], last[::-1]])
    return lines


def _reloop(lines, pen: complex, tolerance: float):
    """Start every closed line at the vertex nearest to where the pen comes from."""
    import vpype as vp

    out = []
    for line in lines:
        if len(line) > 3 and abs(line[0] - line[-1]) <= tolerance:
            line = vp.reloop(line, int(np.argmin(np.abs(line[:-1] - pen))))
        out.append(line)
        pen = line[-1]
    return vp.LineCollection(out)


def travel(plan: PlotPlan, park: complex = 0j) -> dict:
    """Pen-up travel in mm: per layer (inside it, all passes), between layers and to/from ``park``."""
    per_layer: dict[str, float] = {}
    between = 0.0
    pen = park
    first = True
    for step in plan.steps:
        if not isinstance(step, Pass):
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
        else:
            between += arrive
        per_layer[step.name] = per_layer.get(step.name, 0.0) + inside * step.tool.passes + loop_back * (step.tool.passes - 1)
        pen = lines.lines[-1][-1]
    per_layer["between layers"] = between
    per_layer["to park"] = abs(pen - park)
    total = sum(per_layer.values())
    return {"layers": per_layer, "total": total}
