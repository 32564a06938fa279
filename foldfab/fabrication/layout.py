"""A design laid out on the sheet as a plot plan: placed, layered, chained, optimized.

Layers are one vpype ``Document``: valley, mountain, cut, in that order; the outline is cut
last, as closed loops, so the sheet does not move while it is scored.  A two-sided job's
mountains and cut are mirrored for the back of the sheet.
"""

from __future__ import annotations

import numpy as np

from foldfab.design import Design
from foldfab.devices import Blade, DeviceProfile, Tool
from foldfab.errors import FoldfabError
from foldfab.fabrication.plan import Pass, Pause, PlotPlan, collection
from foldfab.fabrication.spec import FLIPS, LAYERS, MARKS, FabricationSpec, flip_message, job_spec


def place(design: Design, device: DeviceProfile, spec: FabricationSpec):
    """Where ``design`` goes on the sheet: (placement, sheet size); a design that does not fit is an error.

    ``spec.scale`` "fit" is the largest scale at which the design fits the sheet less its margin,
    within the device's reach (on both sides of a two-sided job's sheet), turned if that fits
    better: computed from the extents, then placed and checked like any given scale."""
    from foldfab.fabrication.placement import fit, largest_scale, usable

    pts = design.crease_pattern.vertices
    bounds = (complex(*pts.min(axis=0)), complex(*pts.max(axis=0)))
    margin = spec.margin
    try:
        swing = _swing(design, device, spec)
        sheet, area, reach = _reachable(device, spec, swing)
        margin = max(margin, swing)  # nor past the sheet's edge
        scale = spec.scale
        if scale == "fit":
            scale = largest_scale(bounds, usable(sheet, area, margin, reach), spec.rotate)
        placement = fit(bounds, sheet, area, margin, scale, spec.rotate, reach)
    except FoldfabError as exc:
        raise FoldfabError(f"{design.job.path}: {device.name}: {exc}") from None
    width, height = placement.size
    if min(width, height) < SMALLEST_STEPS * device.resolution:
        raise FoldfabError(
            f"{design.job.path}: {device.name}: the design is {width:.3g} x {height:.3g} mm at scale {placement.scale:g}, "
            f"under {SMALLEST_STEPS} of the device's steps ({device.resolution:g} mm) across, so its creases would run "
            "together; set a larger [fabrication].scale (1 is the design's own size)")
    return placement, sheet


def reachable(design: Design, device: DeviceProfile,
              spec: FabricationSpec) -> tuple[tuple[float, float], tuple, str]:
    """The sheet, the part of it the design's lines may take (x0, y0, x1, y1, sheet mm): the
    device's reach, on both sides of a two-sided job's sheet, less a drag knife's swing; and the
    words for that part, for errors."""
    return _reachable(device, spec, _swing(design, device, spec))


def _reachable(device: DeviceProfile, spec: FabricationSpec,
               swing: float) -> tuple[tuple[float, float], tuple, str]:
    """:func:`reachable`, the knife's ``swing`` (:func:`_swing`) given."""
    sheet = spec.sheet or device.sheet
    area = device.frame(sheet).device_rect_on_sheet(*device.plottable_area)
    reach = "the device's plottable area"
    if spec.strategy == "two-sided":
        area = both_sides(area, sheet, spec.flip_edge)
        reach += f" on both sides of the sheet (flipped {FLIPS[spec.flip_edge]})"
    if swing:  # the knife's axis goes up to its blade offset beyond the lines it cuts
        area = (area[0] + swing, area[1] + swing, area[2] - swing, area[3] - swing)
        reach += f" less the {swing:g} mm blade offset the knife swings out by"
    return sheet, area, reach


def _swing(design: Design, device: DeviceProfile, spec: FabricationSpec) -> float:
    """How far a drag knife's axis goes beyond the lines it cuts: the largest blade offset."""
    return max((blade.offset for blade in layer_blades(design, device, spec)[0].values() if blade), default=0.0)


def both_sides(area: tuple[float, float, float, float], sheet: tuple[float, float],
               flip_edge: str) -> tuple[float, float, float, float]:
    """The part of ``area`` (x0, y0, x1, y1, sheet mm) that the device reaches on the front of
    the sheet and, once it is flipped about ``flip_edge``, on its back: the back's strokes are
    the front's mirrored, so a two-sided design must lie where both land within reach."""
    reach = _both_sides(area, sheet, flip_edge)
    if reach is None:
        x0, y0, x1, y1 = area
        axis = 0 if flip_edge == "left" else 1
        size = sheet[axis]
        name = "x" if axis == 0 else "y"
        other = "top" if flip_edge == "left" else "left"
        advice = (f"set [fabrication].flip_edge = \"{other}\" or use a sheet the device reaches whole"
                  if _both_sides(area, sheet, other) is not None else
                  "flipped either way the sheet is not reached on both sides: use a sheet the device "
                  "reaches whole, or the force strategy")
        raise FoldfabError(
            f"the device reaches {name} {area[axis]:g}..{area[axis + 2]:g} mm of the {size:g} mm sheet, and "
            f"flipped {FLIPS[flip_edge]} its back would need {name} {size - area[axis + 2]:g}..{size - area[axis]:g} mm: "
            f"no part of the sheet is reached on both sides; {advice}")
    return reach


def _both_sides(area: tuple[float, float, float, float], sheet: tuple[float, float],
                flip_edge: str) -> tuple[float, float, float, float] | None:
    """:func:`both_sides`, None where no part of the sheet is reached on both sides."""
    x0, y0, x1, y1 = area
    axis = 0 if flip_edge == "left" else 1
    lo, hi, size = (x0, x1, sheet[0]) if axis == 0 else (y0, y1, sheet[1])
    lo, hi = max(lo, size - hi), min(hi, size - lo)
    if hi <= lo:
        return None
    return (lo, y0, hi, y1) if axis == 0 else (x0, lo, x1, hi)


SMALLEST_STEPS = 10
"""A placed design must be at least this many plotter steps wide and high."""


def build_plan(design: Design, device: DeviceProfile, spec: FabricationSpec | None = None) -> PlotPlan:
    """The plot plan of ``design`` on ``device``: placed, layered, optimized, never cropped."""
    if spec is None:
        spec = job_spec(design.job)
    placement, sheet = place(design, device, spec)
    tools, _ = layer_tools(design, device, spec)
    return finish_plan(lay_out(design, device, spec, placement, sheet, tools), device, spec)


def layer_tools(design: Design, device: DeviceProfile,
                spec: FabricationSpec) -> tuple[dict[str, Tool], list[str]]:
    """The tool of each layer, and a warning line for each job setting the device does not have.

    Perforation dashes are cuts: with the perforate strategy the valley and mountain passes
    start from the profile's cut settings, and ``[fabrication.layers.valley]`` etc. override them.
    """
    from foldfab.devices.blade import without_blade_keys

    source = f"{design.job.path}: [fabrication.layers]"
    media = device.media_overrides(spec.media, f"{design.job.path}: [fabrication] media")
    tools, warnings = {}, []
    for name in LAYERS:
        like = "cut" if spec.strategy == "perforate" else name
        overrides, ignored = device.supported({**media.get(like, {}), **without_blade_keys(spec.layers.get(name, {}))},
                                              f"{design.job.path}: [fabrication.layers.{name}]")
        warnings += ignored
        tools[name] = device.tool_for(name, overrides, source, like=like)
    return tools, warnings + layer_blades(design, device, spec)[1]


def layer_blades(design: Design, device: DeviceProfile,
                 spec: FabricationSpec) -> tuple[dict[str, Blade | None], list[str]]:
    """The drag-knife compensation of each layer (None: none), and a warning line for each job
    blade setting ignored because the device's firmware compensates.

    Only layers the blade cuts are compensated: the cut, and with the perforate strategy the
    creases' dashes (from the profile's ``[layers.cut]``); a blade setting on a scored layer is
    an error.  ``[fabrication.layers.NAME]`` overrides the profile's setting."""
    from foldfab.devices.blade import blade_keys, take_blade
    from foldfab.devices.checks import _Reader

    blades: dict[str, Blade | None] = {}
    warnings = []
    for name in LAYERS:
        where = f"{design.job.path}: [fabrication.layers.{name}]"
        given = blade_keys(spec.layers.get(name, {}))
        cuts = name == "cut" or spec.strategy == "perforate"
        if given and not cuts:
            key = next(iter(given))
            raise FoldfabError(f"{where}: {key} = {given[key]!r} on a scored layer: the blade presses the {name} "
                               "creases, it does not cut them; remove it (blade settings apply to cut layers: "
                               "the cut, and the creases' dashes with the perforate strategy)")
        if device.firmware_blade_offset:
            warnings += [f"{where}.{key} = {value!r} ignored: {device.name} compensates its blade itself "
                         "(firmware_blade_offset = true)" for key, value in given.items()]
            blades[name] = None
            continue
        base = device.blades.get("cut" if cuts else name)
        reader = _Reader(dict(given), f"{design.job.path}: [fabrication.layers]", f"layers.{name}.")
        blade = take_blade(reader, base or Blade()) if given else base
        blades[name] = blade if cuts and blade is not None and (blade.offset > 0 or blade.overcut > 0) else None
    return blades, warnings


def lay_out(design: Design, device: DeviceProfile, spec: FabricationSpec, placement, sheet,
            tools: dict[str, Tool]) -> PlotPlan:
    """The layers of ``design`` placed on the sheet, creases chained, in crease-pattern order,
    each drawn with its tool of ``tools`` (:func:`layer_tools`)."""
    import vpype as vp

    from foldfab.fabrication import scoring
    from foldfab.fabrication.placement import mirror

    blades, _ = layer_blades(design, device, spec)
    cp = design.crease_pattern
    placed = placement.apply(scoring.vertex_points(cp))
    strokes = {"valley": scoring.crease_strokes(cp, "V", placed), "mountain": scoring.crease_strokes(cp, "M", placed),
               "cut": scoring.outline_strokes(cp, placed)}
    marks = [placement.apply(m[:, 0] + 1j * m[:, 1]) for m in design.marks]
    if spec.strategy == "two-sided":
        flip = (lambda p: mirror(p, sheet[0])) if spec.flip_edge == "left" else \
               (lambda p: p.real + 1j * (sheet[1] - p.imag))
        for name in ("mountain", "cut"):
            points, starts = strokes[name]
            strokes[name] = flip(points), starts
    check_strokes(design, spec, strokes)

    doc = vp.Document()
    doc.page_size = sheet
    steps: list = []
    for name, (layer_id, colour) in LAYERS.items():
        if spec.strategy == "two-sided" and name == "mountain":
            steps.append(Pause(flip_message(spec, device)))
        doc.layers[layer_id] = collection(scoring.split_strokes(*strokes[name]))
        doc.layers[layer_id].set_property("vp_name", name)
        doc.layers[layer_id].set_property("vp_color", vp.Color(colour))
        steps.append(Pass(layer_id, name, tools[name], blades[name]))
        if name == "valley" and marks:   # on the front, with the scoring tool: drawn, never cut
            add_marks(doc, steps, marks, device)
    return PlotPlan(doc, steps, sheet)


def add_marks(doc, steps: list, marks: list[np.ndarray], device: DeviceProfile) -> None:
    """The ``marks`` layer (:data:`MARKS`): a split piece's numbers and match letters, strokes
    in the cut layer's colour drawn with the valley's scoring tool (the profile's, never the
    perforate strategy's cutting one)."""
    import vpype as vp

    layer_id, colour = MARKS
    doc.add(marks, layer_id)
    doc.layers[layer_id].set_property("vp_name", "marks")
    doc.layers[layer_id].set_property("vp_color", vp.Color(colour))
    steps.append(Pass(layer_id, "marks", device.tool_for("marks", like="valley")))


def check_strokes(design: Design, spec: FabricationSpec, strokes: dict[str, tuple[np.ndarray, np.ndarray]]) -> None:
    """Refuse, before the plan is optimized or perforated, a program of more strokes than
    ``spec.max_strokes``: one per line, one per dash of a perforated crease.  ``strokes``
    holds each layer's lines as :func:`~foldfab.fabrication.scoring.crease_strokes` gives them."""
    from foldfab.fabrication import scoring

    count = 0
    for name, (points, starts) in strokes.items():
        if spec.strategy == "perforate" and name in spec.perforation:
            count += scoring.dash_bound(scoring.stroke_segments(points, starts), spec.perforation[name], spec.clearance)
        else:
            count += len(starts)
    if count > spec.max_strokes:
        finer = " or a longer [fabrication.perforate] pattern" if spec.strategy == "perforate" else ""
        raise FoldfabError(f"{design.job.path}: the program would draw up to {count:,} strokes, more than the limit of "
                           f"{spec.max_strokes:,}; use a design of fewer faces{finer}, or set "
                           "[fabrication].max_strokes = N in the job to fabricate it anyway")


def _segments(lines) -> np.ndarray:
    """The segments (S, 2) complex of polylines ``lines``, in order."""
    from foldfab.fabrication.scoring import stroke_segments

    sizes = np.array([len(line) for line in lines], dtype=np.intp)
    return stroke_segments(np.concatenate(lines) if len(sizes) else np.zeros(0, complex), np.cumsum(sizes) - sizes)


def finish_plan(layout: PlotPlan, device: DeviceProfile, spec: FabricationSpec,
                optimize: str | None = None) -> PlotPlan:
    """``layout`` optimized (by ``optimize``, default the spec's method); for the perforate
    strategy, its creases cut into dashes; then the lines of each pass with a blade moved to
    the drag knife's axis path (:mod:`foldfab.fabrication.blade`: last, since it follows each
    line's final direction).  ``layout`` itself is left as it is."""
    import vpype as vp

    from foldfab.fabrication import scoring
    from foldfab.fabrication.blade import compensate
    from foldfab.fabrication.optimize import optimize_plan

    park = park_position(device, layout.sheet)
    perforated = frozenset(("valley", "mountain")) if spec.strategy == "perforate" else frozenset()
    plan = optimize_plan(layout, optimize or spec.optimize, device.resolution, park,
                         keep_vertices=perforated, tool_changer=device.tool_changer)
    if not perforated and not any(isinstance(step, Pass) and step.blade for step in plan.steps):
        return plan
    doc = plan.document.clone()  # metadata only: the layers are added below
    for step in plan.steps:
        if not isinstance(step, Pass):
            continue
        layer = plan.document.layers[step.layer_id]
        lines = None
        if step.name in perforated:
            # Dashes follow the optimized creases in order; every crease vertex gets its clearance.
            lines = list(scoring.perforate(_segments(layer), spec.perforation[step.name], spec.clearance))
        if step.blade is not None:
            lines = compensate(layer.lines if lines is None else lines, step.blade, device.resolution)
        if lines is not None:
            changed = vp.LineCollection(lines)
            for key, value in layer.metadata.items():
                changed.set_property(key, value)
            layer = changed
        doc.add(layer, step.layer_id, with_metadata=True)
    return PlotPlan(doc, list(plan.steps), plan.sheet)


def park_position(device: DeviceProfile, sheet: tuple[float, float]) -> complex:
    """The device's park position on the sheet (where the pen starts and ends)."""
    frame = device.frame(sheet)
    return complex(*frame.to_sheet(np.array([device.motion.park]) * device.units_per_mm)[0])
