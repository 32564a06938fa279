"""The studio's fabrication panel, served: a device's settings with their ranges, a design laid
out on the device's sheets with its time estimate, the dry run's strokes, the printable template.

The panel edits the job's ``[fabrication]`` table, which travels with every request and is
checked there as every command checks it (:func:`~foldfab.fabrication.spec.job_spec`); the
tool settings are checked by the device profile when the program is made
(:func:`~foldfab.fabricate.fabricate_sheets`, as ``foldfab export`` makes it).  So the panel
shows exactly what the command line would do with the saved job, and refuses what it refuses.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from foldfab.design import Design
from foldfab.devices import DeviceProfile
from foldfab.errors import FoldfabError

TOOL_SETTINGS = ("force", "speed", "passes", "power")
"""The per-layer settings the panel offers (the pen is the profile's)."""
MAX_DRY_RUN_POINTS = 2_000_000
"""The most stroke points a dry run sends the browser for its stroke slider (a design of
:data:`~foldfab.studio.api.STUDIO_MAX_FACES` faces draws fewer)."""


def device_settings(device: DeviceProfile) -> dict[str, Any]:
    """What the panel offers for ``device``: its sheet, each layer's default tool, the range of
    each setting (None: the device has no such setting) and its media presets."""
    from foldfab.devices.checks import SHEETS
    from foldfab.fabrication.optimize import METHODS
    from foldfab.fabrication.spec import FLIP_EDGES, STRATEGIES

    limits, language = device.limits, device.language
    ranges = {"force": None if device.lacks("force") else list(limits.force or (0, None)),
              "speed": list(limits.speed or (0, None)), "passes": [1, 100],
              "power": [0, 1] if device.laser else None}
    steps = {"force": language.force_step, "speed": language.speed_step, "passes": 1, "power": None}
    layers = {name: {"pen": layer.pen, "force": layer.force, "speed": layer.speed, "passes": layer.passes,
                     "power": layer.power} for name, layer in device.layers.items()}
    media = [{"name": name, "description": preset.description, "score": dict(preset.score), "cut": dict(preset.cut)}
             for name, preset in device.media.items()]
    return {"device": device.name, "model": device.model, "sheet": list(device.sheet),
            "plottable_area": list(device.plottable_area), "sheets": [name.capitalize() if name != "letter" else "Letter"
                                                                     for name in SHEETS],
            "strategies": list(STRATEGIES), "optimize": list(METHODS), "flip_edges": list(FLIP_EDGES),
            "settings": [key for key in TOOL_SETTINGS if ranges[key] is not None],
            "ranges": ranges, "steps": steps, "layers": layers, "media": media}


def _rect(placement, offset: np.ndarray, x0: float, y0: float, x1: float, y1: float) -> list[list[float]]:
    """The sheet rectangle (x0, y0)-(x1, y1) (sheet mm) in the whole design's crease-pattern mm."""
    corners = placement.invert(np.array([complex(x0, y0), complex(x1, y0), complex(x1, y1), complex(x0, y1)]))
    return [[round(float(p.real + offset[0]), 4), round(float(p.imag + offset[1]), 4)] for p in corners]


def sheet_outline(placement, sheet: tuple[float, float], margin: float,
                  offset: np.ndarray | None = None) -> dict[str, Any]:
    """Where a sheet (w, h mm) and its margin lie round the design placed on it: four corners
    each in crease-pattern mm (the piece's ``offset`` added), as the crease view draws them."""
    offset = np.zeros(2) if offset is None else offset
    w, h = sheet
    return {"sheet": [w, h], "outline": _rect(placement, offset, 0, 0, w, h),
            "margin_outline": _rect(placement, offset, margin, margin, w - margin, h - margin) if 2 * margin < min(w, h) else None}


def fabrication_answer(design: Design, device: DeviceProfile) -> dict[str, Any]:
    """``design`` laid out for ``device`` as ``foldfab export`` lays it out: every sheet's outline
    and margin around the design (crease-pattern mm, so the crease view draws them over the
    pattern), the piece each sheet holds when split, the tools, and the estimate of all sheets."""
    from foldfab.fabricate import fabricate_sheets
    from foldfab.fabrication.plan import Pass
    from foldfab.programs.estimate import estimate_drawn
    from foldfab.programs.interpret import drawn

    fabs = fabricate_sheets(design, device)
    sheets, layers = [], {}
    total = {"time_s": 0.0, "drawn_mm": 0.0, "travel_mm": 0.0, "pen_lifts": 0, "program_bytes": 0}
    for number, fab in enumerate(fabs, 1):
        times = estimate_drawn(drawn(fab.program, device, fab.plan.sheet), device)  # as export reports it
        piece = fab.piece
        offset = piece.offset if piece is not None else np.zeros(2)
        box = None
        if piece is not None:
            v = piece.crease_pattern.vertices + offset
            box = [float(c) for c in (*v.min(axis=0), *v.max(axis=0))]
        sheets.append({"number": number, **sheet_outline(fab.placement, fab.plan.sheet, fab.spec.margin, offset),
                       "piece": box, "time_s": round(times.total, 1)})
        for name, layer in times.layers.items():
            into = layers.setdefault(name, {"drawn_mm": 0.0, "pen_lifts": 0, "time_s": 0.0})
            into["drawn_mm"] += layer.drawn_length
            into["pen_lifts"] += layer.pen_lifts
            into["time_s"] += layer.time
            total["drawn_mm"] += layer.drawn_length
            total["travel_mm"] += layer.travel_length
            total["pen_lifts"] += layer.pen_lifts
        total["time_s"] += times.total
        total["program_bytes"] += len(fab.program.text)
    first = fabs[0]
    tools = {step.name: {key: getattr(step.tool, key) for key in ("pen", *TOOL_SETTINGS)}
             for step in first.plan.steps if isinstance(step, Pass)}
    return {"device": device.name, "strategy": first.spec.strategy, "scale": first.placement.scale,
            "scale_fitted": first.spec.scale == "fit", "rotated": first.placement.rotated,
            "sheets": sheets, "tools": tools, "warnings": list(first.warnings),
            "layers": {name: {k: round(v, 1) for k, v in layer.items()} for name, layer in layers.items()},
            "estimate": {k: round(v, 1) if isinstance(v, float) else v for k, v in total.items()}}


def dry_run_strokes(run) -> dict[str, Any]:
    """The strokes of an interpreted program (:func:`~foldfab.programs.interpret.interpret`) in
    the order the device draws them, for the dry run's stroke slider: flat sheet-mm points, where
    each stroke starts in them (and the end), and each stroke's layer (an index into ``layers``)."""
    from foldfab.programs.machine import from_interpretation

    count = sum(len(s.points) for s in run.strokes)
    if count > MAX_DRY_RUN_POINTS:
        return {"points": [], "starts": [], "layer": [], "layers": [], "omitted":
                f"{count:,} stroke points: more than the {MAX_DRY_RUN_POINTS:,} the stroke slider shows"}
    arrays = from_interpretation(run)
    return {"points": arrays.points.round(3).ravel().tolist(), "starts": [*arrays.starts.tolist(), count],
            "layer": arrays.layers.tolist(), "layers": list(arrays.names)}


def print_options(design: Design, paper: str):
    """The template's options as ``foldfab print JOB --paper PAPER`` takes them: the job's
    scale ("fit" prints at 1, true size)."""
    from foldfab.printing.paper import PrintOptions, check_options, job_print_scale, parse_paper

    size, name, turnable = parse_paper(paper, "paper")
    options = PrintOptions(size, name, turnable, scale=job_print_scale(design.job))
    check_options(options)
    return options


def write_print(design: Design, target: Path, options) -> dict[str, Any]:
    """Write ``design``'s printable template to ``target`` (PDF, or SVG pages)."""
    from foldfab.printing.output import write_template

    try:
        template, written = write_template(design, target, options)
    except OSError as exc:
        raise FoldfabError(f"{target}: cannot write: {exc.strerror or exc}") from None
    return {"written": [str(p) for p in written], "pages": len(template.pages), "paper": options.paper_name}
