"""The ``[fabrication]`` table of a job: strategy, sheet, placement, optimization, tools.

The strategy (``force``, ``perforate``, ``two-sided``) chooses how creases are made; layers
are valley, mountain, cut, in that order (flat creases are never scored).  This module owns
the table: it validates it for every command that reads a job.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from foldfab.devices import parse_sheet
from foldfab.job import TomlTable
from foldfab.limits import MAX_STROKES

if TYPE_CHECKING:
    from foldfab.devices import DeviceProfile
    from foldfab.job import Job

STRATEGIES = ("force", "perforate", "two-sided")
LAYERS = {"valley": (1, "#0000ff"), "mountain": (2, "#ff0000"), "cut": (3, "#000000")}
MARKS = (4, "#000000")
"""Layer id and colour (the cut's) of a split piece's match marks: drawn or scored, never cut."""
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
    split: str | tuple[int, ...] = ()            # "auto", or the mirror planes to cut after
    split_height: tuple[int, ...] = ()           # the line elements to cut along
    media: str | None = None
    """A media preset of the device (``[media.NAME]`` in its profile): its tool settings for
    scoring and cutting, under the job's own ``layers``."""


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
                                                    "flip_edge", "perforate", "layers", "max_strokes",
                                                    "split", "split_height", "media"))
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
    split, split_height = parse_split(table)
    media = table.string("media")
    return FabricationSpec(strategy, sheet, margin, rotate, scale, optimize, flip_edge, perforation, clearance, layers,
                           max_strokes, split, split_height, media)



def parse_split(table: TomlTable) -> tuple[str | tuple[int, ...], tuple[int, ...]]:
    """``split`` ("auto" or a list of trajectory corners) and ``split_height`` (a list of profile
    points): where the design is cut into pieces (foldfab.geometry.split).  Whether each cut
    lies inside the design is checked when the design is built."""
    split = table.get("split", [])
    if split != "auto" and not _cut_list(split):
        table.fail("split", f"expected \"auto\" (the fewest pieces that fit the sheet) or a list of trajectory corners "
                            f"to cut after, such as [4, 8], got {split!r}")
    height = table.get("split_height", [])
    if not _cut_list(height):
        table.fail("split_height", f"expected a list of profile points to cut after, such as [3], got {height!r}")
    return (split if split == "auto" else tuple(sorted(split))), tuple(sorted(height))


def _cut_list(value: Any) -> bool:
    """A list of distinct whole numbers from 1 (a cut after corner or point 0 is no cut)."""
    return (isinstance(value, list) and len(value) <= MAX_CUTS and len(set(value)) == len(value)
            and all(isinstance(v, int) and not isinstance(v, bool) and v >= 1 for v in value))


MAX_CUTS = 1000
"""The most cuts a ``split`` list may name (each is a piece: a thousand sheets is plenty)."""


def job_spec(job: Job) -> FabricationSpec:
    """The job's ``[fabrication]`` table, validated.  Every command that reads a job calls this,
    designing ones too, so that a mistake there is the job's whichever command reads it."""
    return parse_fabrication(job.fabrication, str(job.path))


def flip_message(spec: FabricationSpec, device: DeviceProfile) -> str:
    """The operator's instruction at the flip of a two-sided job."""
    return (f"Valleys are scored. Flip the sheet {FLIPS[spec.flip_edge]}, "
            f"put its corner back against the {device.origin} registration corner of {device.name}, then continue: "
            "mountains are scored on the back, then the outline is cut.")
