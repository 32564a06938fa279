"""Fabrication: a design and a device profile become a plot plan, then a program.

The job's ``[fabrication]`` table chooses the strategy (``force``,
``perforate``, ``two-sided``), the sheet, margin, rotation, scale, the travel
optimization and per-layer tool overrides.  Layers are one vpype ``Document``:
valley, mountain, cut, in that order; flat creases are never scored and the
outline is cut last, as closed loops, so the sheet does not move while it is
scored.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any

import numpy as np

from foldfab.design import Design
from foldfab.devices import DeviceProfile, parse_sheet
from foldfab.errors import FoldfabError
from foldfab.job import TomlTable
from foldfab.limits import MAX_STROKES
from foldfab.fabrication.plan import Pass, Pause, PlotPlan, Tool

STRATEGIES = ("force", "perforate", "two-sided")
LAYERS = {"valley": (1, "#0000ff"), "mountain": (2, "#ff0000"), "cut": (3, "#000000")}
FLIPS = {"left": "left-right (about the vertical axis)", "top": "top-bottom (about the horizontal axis)"}
"""How the sheet of a two-sided job turns, by ``flip_edge``."""
FLIP_EDGES = tuple(FLIPS)


def placement_text(scale: float, fitted: bool, rotated: bool) -> str:
    """The scale a design is drawn at and whether it is turned, as the report and the preview say it."""
    return f"scale {scale:.4g}" + (" (fitted to the sheet)" if fitted else "") + (", turned 90 degrees" if rotated else "")


@dataclass(frozen=True)
class FabricationSpec:
    """The validated ``[fabrication]`` table."""

    strategy: str = "force"
    sheet: tuple[float, float] | None = None     # None: the device's default sheet
    margin: float = 10.0
    rotate: str = "auto"                          # auto | yes | no
    scale: float | str = 1.0                      # a number > 0, or "fit": the largest that fits
    optimize: str = "greedy"                      # none | greedy | two-opt
    flip_edge: str = "left"
    perforation: dict[str, tuple[float, ...]] = field(
        default_factory=lambda: {"valley": (1.0, 1.0), "mountain": (2.0, 1.0, 0.5, 1.0)})
    clearance: float = 1.0
    layers: dict[str, dict[str, Any]] = field(default_factory=dict)
    max_strokes: int = MAX_STROKES


PERFORATION_MIN = 0.1
"""mm: the shortest cut or gap of a perforation.  A blade cannot cut a shorter piece apart from
the next one (a plotter step is 0.025 mm), and every cut is a pen lift: shorter ones would
turn a crease into a near-solid slit drawn by a million lifts."""
PERFORATION_MAX = 1000.0
"""mm: the longest cut or gap of a perforation (a metre)."""


def parse_fabrication(data: dict, source: str) -> FabricationSpec:
    """Validate a job's ``[fabrication]`` table; errors name the key."""
    from foldfab.fabrication.optimize import METHODS

    table = TomlTable(source, "fabrication", data, ("strategy", "sheet", "margin", "rotate", "scale", "optimize",
                                                    "flip_edge", "perforate", "layers", "max_strokes"))
    defaults = FabricationSpec()
    strategy = table.string("strategy", "force", choices=STRATEGIES)
    sheet = None
    if table.has("sheet"):
        sheet = parse_sheet(table.get("sheet"))
        if sheet is None:
            table.fail("sheet", f"expected \"A4\", \"A3\", \"Letter\" (optionally \"landscape\") or [width, height] in mm, "
                                f"got {table.get('sheet')!r}")
    margin = table.number("margin", defaults.margin, minimum=0.0)
    rotate_value = table.get("rotate", "auto")
    if rotate_value not in ("auto", True, False):
        table.fail("rotate", f"expected \"auto\", true or false, got {rotate_value!r}")
    rotate = {"auto": "auto", True: "yes", False: "no"}[rotate_value]
    scale = table.get("scale", 1.0)
    if isinstance(scale, bool) or not (scale == "fit" or isinstance(scale, (int, float))):
        table.fail("scale", f"expected a number > 0 or \"fit\" (the largest scale that fits the sheet), got {scale!r}")
    if scale != "fit":
        scale = table.number("scale", 1.0, exclusive_minimum=0.0)
    optimize = table.string("optimize", "greedy", choices=METHODS)
    flip_edge = table.string("flip_edge", "left", choices=FLIP_EDGES)
    perforation = dict(defaults.perforation)
    clearance = defaults.clearance
    if table.has("perforate"):
        sub = TomlTable(source, "fabrication.perforate", table.get("perforate"), ("valley", "mountain", "clearance"))
        for kind in ("valley", "mountain"):
            if sub.has(kind):
                pattern = sub.get(kind)
                if (not isinstance(pattern, list) or len(pattern) < 2 or len(pattern) % 2
                        or any(isinstance(v, bool) or not isinstance(v, (int, float))
                               or not PERFORATION_MIN <= v <= PERFORATION_MAX for v in pattern)):
                    sub.fail(kind, f"expected an even-length list [cut, gap, ...] of lengths from {PERFORATION_MIN:g} "
                                   f"to {PERFORATION_MAX:g} mm, got {pattern!r}")
                perforation[kind] = tuple(float(v) for v in pattern)
        clearance = sub.number("clearance", clearance, minimum=0.0)
    layers: dict[str, dict[str, Any]] = {}
    if table.has("layers"):
        sub = TomlTable(source, "fabrication.layers", table.get("layers"), LAYERS)
        for name in LAYERS:
            if sub.has(name):
                value = sub.get(name)
                if not isinstance(value, dict):
                    sub.fail(name, "expected a table of tool settings (pen, force, speed, passes)")
                layers[name] = value
    max_strokes = table.integer("max_strokes", MAX_STROKES, minimum=1)
    return FabricationSpec(strategy, sheet, margin, rotate, scale, optimize, flip_edge, perforation, clearance, layers,
                           max_strokes)


def flip_message(spec: FabricationSpec, device: DeviceProfile) -> str:
    """The operator's instruction at the flip of a two-sided job."""
    return (f"Valleys are scored. Flip the sheet {FLIPS[spec.flip_edge]}, "
            f"put its corner back against the {device.origin} registration corner of {device.name}, then continue: "
            "mountains are scored on the back, then the outline is cut.")


def place(design: Design, device: DeviceProfile, spec: FabricationSpec):
    """Where ``design`` goes on the sheet: (placement, sheet size); a design that does not fit is an error.

    ``spec.scale`` "fit" is the largest scale at which the design fits the sheet less its margin,
    within the device's reach (on both sides of a two-sided job's sheet), turned if that fits
    better: computed from the extents, then placed and checked like any given scale."""
    from foldfab.fabrication.placement import fit, largest_scale, usable

    sheet = spec.sheet or device.sheet
    area = device.frame(sheet).device_rect_on_sheet(*device.plottable_area)
    reach = "the device's plottable area"
    pts = design.crease_pattern.vertices
    bounds = (complex(*pts.min(axis=0)), complex(*pts.max(axis=0)))
    try:
        if spec.strategy == "two-sided":
            area = both_sides(area, sheet, spec.flip_edge)
            reach += f" on both sides of the sheet (flipped {FLIPS[spec.flip_edge]})"
        scale = spec.scale
        if scale == "fit":
            scale = largest_scale(bounds, usable(sheet, area, spec.margin, reach), spec.rotate)
        placement = fit(bounds, sheet, area, spec.margin, scale, spec.rotate, reach)
    except FoldfabError as exc:
        raise FoldfabError(f"{design.job.path}: {device.name}: {exc}") from None
    width, height = placement.size
    if min(width, height) < SMALLEST_STEPS * device.resolution:
        raise FoldfabError(
            f"{design.job.path}: {device.name}: the design is {width:.3g} x {height:.3g} mm at scale {placement.scale:g}, "
            f"under {SMALLEST_STEPS} of the device's steps ({device.resolution:g} mm) across, so its creases would run "
            "together; set a larger [fabrication].scale (1 is the design's own size)")
    return placement, sheet


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
        spec = parse_fabrication(design.job.fabrication, str(design.job.path))
    placement, sheet = place(design, device, spec)
    tools, _ = layer_tools(design, device, spec)
    return finish_plan(lay_out(design, device, spec, placement, sheet, tools), device, spec)


def layer_tools(design: Design, device: DeviceProfile,
                spec: FabricationSpec) -> tuple[dict[str, Tool], list[str]]:
    """The tool of each layer, and a warning line for each job setting the device does not have.

    Perforation dashes are cuts: with the perforate strategy the valley and mountain passes
    start from the profile's cut settings, and ``[fabrication.layers.valley]`` etc. override them.
    """
    source = f"{design.job.path}: [fabrication.layers]"
    tools, warnings = {}, []
    for name in LAYERS:
        overrides, ignored = device.supported(spec.layers.get(name, {}),
                                              f"{design.job.path}: [fabrication.layers.{name}]")
        warnings += ignored
        like = "cut" if spec.strategy == "perforate" else name
        tools[name] = device.tool_for(name, overrides, source, like=like)
    return tools, warnings


def lay_out(design: Design, device: DeviceProfile, spec: FabricationSpec, placement, sheet,
            tools: dict[str, Tool]) -> PlotPlan:
    """The layers of ``design`` placed on the sheet, creases chained, in crease-pattern order,
    each drawn with its tool of ``tools`` (:func:`layer_tools`)."""
    import vpype as vp

    from foldfab.fabrication import scoring
    from foldfab.fabrication.placement import mirror

    cp = design.crease_pattern
    placed = placement.apply(scoring.vertex_points(cp))
    lines = {"valley": scoring.crease_lines(cp, "V", placed), "mountain": scoring.crease_lines(cp, "M", placed),
             "cut": scoring.outline_loops(cp, placed)}
    if spec.strategy == "two-sided":
        flip = (lambda p: mirror(p, sheet[0])) if spec.flip_edge == "left" else \
               (lambda p: p.real + 1j * (sheet[1] - p.imag))
        lines["mountain"] = [flip(p) for p in lines["mountain"]]
        lines["cut"] = [flip(p) for p in lines["cut"]]
    check_strokes(design, spec, lines)

    doc = vp.Document()
    doc.page_size = sheet
    steps: list = []
    for name, (layer_id, colour) in LAYERS.items():
        if spec.strategy == "two-sided" and name == "mountain":
            steps.append(Pause(flip_message(spec, device)))
        doc.add(lines[name], layer_id)
        doc.layers[layer_id].set_property("vp_name", name)
        doc.layers[layer_id].set_property("vp_color", vp.Color(colour))
        steps.append(Pass(layer_id, name, tools[name]))
    return PlotPlan(doc, steps, sheet)


def check_strokes(design: Design, spec: FabricationSpec, lines: dict[str, list[np.ndarray]]) -> None:
    """Refuse, before the plan is optimized or perforated, a program of more strokes than
    ``spec.max_strokes``: one per line, one per dash of a perforated crease."""
    from foldfab.fabrication import scoring

    count = 0
    for name, layer in lines.items():
        if spec.strategy == "perforate" and name in spec.perforation:
            count += scoring.dash_bound(_segments(layer), spec.perforation[name], spec.clearance)
        else:
            count += len(layer)
    if count > spec.max_strokes:
        finer = " or a longer [fabrication.perforate] pattern" if spec.strategy == "perforate" else ""
        raise FoldfabError(f"{design.job.path}: the program would draw up to {count:,} strokes, more than the limit of "
                           f"{spec.max_strokes:,}; use a design of fewer faces{finer}, or set "
                           "[fabrication].max_strokes = N in the job to fabricate it anyway")


def _segments(lines) -> np.ndarray:
    """The segments (S, 2) complex of polylines ``lines``, in order."""
    segments = [np.column_stack([line[:-1], line[1:]]) for line in lines]
    return np.concatenate(segments) if segments else np.zeros((0, 2), complex)


def finish_plan(layout: PlotPlan, device: DeviceProfile, spec: FabricationSpec,
                optimize: str | None = None) -> PlotPlan:
    """``layout`` optimized (by ``optimize``, default the spec's method) and, for the perforate
    strategy, its creases cut into dashes.  ``layout`` itself is left as it is."""
    import vpype as vp

    from foldfab.fabrication import scoring
    from foldfab.fabrication.optimize import optimize_plan

    park = park_position(device, layout.sheet)
    perforated = frozenset(("valley", "mountain")) if spec.strategy == "perforate" else frozenset()
    plan = optimize_plan(layout, optimize or spec.optimize, device.resolution, park,
                         keep_vertices=perforated, tool_changer=device.tool_changer)
    if not perforated:
        return plan
    doc = plan.document.clone()  # metadata only: the layers are added below
    for step in plan.steps:
        if not isinstance(step, Pass):
            continue
        layer = plan.document.layers[step.layer_id]
        if step.name in perforated:
            # Dashes follow the optimized creases in order; every crease vertex gets its clearance.
            dashes = scoring.perforate(_segments(layer), spec.perforation[step.name], spec.clearance)
            dashed = vp.LineCollection(list(dashes))
            for key, value in layer.metadata.items():
                dashed.set_property(key, value)
            layer = dashed
        doc.add(layer, step.layer_id, with_metadata=True)
    return PlotPlan(doc, list(plan.steps), plan.sheet)


@dataclass(frozen=True)
class Fabrication:
    """A design made ready for one device: the plan, its program, and the travel it saves."""

    spec: FabricationSpec
    placement: Any          # foldfab.fabrication.placement.Placement: crease-pattern mm -> sheet mm (front side)
    plan: PlotPlan
    program: Any            # foldfab.programs.program.Program
    design: Design
    device: DeviceProfile
    layout: PlotPlan        # the plan before optimization (for the travel it saves)
    warnings: tuple[str, ...] = ()   # job settings the device does not have, ignored

    @property
    def placement_summary(self) -> str:
        """The scale the design is drawn at and whether it is turned (:func:`placement_text`)."""
        return placement_text(self.placement.scale, self.spec.scale == "fit", self.placement.rotated)

    @cached_property
    def travel_after(self) -> dict:
        """Pen-up travel of the plan (:func:`foldfab.fabrication.optimize.travel`)."""
        from foldfab.fabrication.optimize import travel

        return travel(self.plan, park_position(self.device, self.plan.sheet), self.device.tool_changer)

    @cached_property
    def travel_before(self) -> dict:
        """Pen-up travel of the same layers unoptimized (on demand: only reports need it)."""
        from foldfab.fabrication.optimize import travel

        if self.spec.optimize == "none":
            return self.travel_after
        unoptimized = finish_plan(self.layout, self.device, self.spec, optimize="none")
        return travel(unoptimized, park_position(self.device, self.plan.sheet), self.device.tool_changer)


def fabricate(design: Design, device: DeviceProfile, spec: FabricationSpec | None = None,
              scale: float | str | None = None) -> Fabrication:
    """Plan, optimize and write the program of ``design`` for ``device``; ``scale`` (a number
    or "fit", the command line's ``--scale``) replaces the job's ``[fabrication].scale``."""
    from foldfab.programs.program import write_program

    if spec is None:
        spec = parse_fabrication(design.job.fabrication, str(design.job.path))
    if scale is not None:
        spec = replace(spec, scale=scale)
    placement, sheet = place(design, device, spec)
    tools, warnings = layer_tools(design, device, spec)
    layout = lay_out(design, device, spec, placement, sheet, tools)
    plan = finish_plan(layout, device, spec)
    return Fabrication(spec, placement, plan, write_program(plan, device), design, device, layout,
                       tuple(warnings))


def park_position(device: DeviceProfile, sheet: tuple[float, float]) -> complex:
    """The device's park position on the sheet (where the pen starts and ends)."""
    frame = device.frame(sheet)
    return complex(*frame.to_sheet(np.array([device.motion.park]) * device.units_per_mm)[0])
