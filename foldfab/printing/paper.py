"""The printer's paper and the template's options: named sizes, ``[w, h]``, margins, overlap."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from foldfab.devices.checks import SHEETS
from foldfab.errors import FoldfabError
from foldfab.printing.tiles import FOOTER, HEADER

PAPER_MIN = 80.0
"""mm: the smallest paper side, room for the page's labels and a tile of pattern."""
PAPER_MAX = 5000.0
"""mm: the largest paper side (PDF readers refuse pages over 200 inches, 5080 mm)."""
MARGIN_MAX = 50.0
"""mm: the widest margin; printers leave 3-6 mm unprinted, so 10 mm is the default."""
MIN_AREA = (60.0, 40.0)
"""mm: the least room a page must leave inside its margins (across its shorter side) for the
50 mm scale bar, and for the pattern between the header and footer bands."""
OVERLAP_MAX = 30.0
"""mm: the widest overlap between neighbouring tiles."""


def job_print_scale(job) -> float:
    """The scale a template of ``job`` prints at: its ``[fabrication].scale``, where a plotter's
    "fit" (a scale for the plotter's sheet) prints at 1, true size."""
    from foldfab.fabrication.spec import job_spec

    scale = job_spec(job).scale
    return 1.0 if scale == "fit" else scale


@dataclass(frozen=True)
class PrintOptions:
    """How a template is printed: paper size (mm, portrait), whether its orientation is
    chosen (named sizes: whichever needs fewer pages) or fixed, margins, overlap between tiles,
    scale, and the line options."""

    paper: tuple[float, float] = SHEETS["a4"]
    paper_name: str = "A4"
    turnable: bool = True
    margin: float = 10.0
    overlap: float = 6.0
    scale: float = 1.0
    flat: bool = False
    mono: bool = False


def parse_paper(text: str, option: str = "--paper") -> tuple[tuple[float, float], str, bool]:
    """``A4``, ``A3``, ``Letter`` (optionally followed by ``landscape``, which fixes the
    orientation) or ``[w, h]`` in mm: the size, its name, and whether the orientation may turn."""
    words = text.lower().split()
    if words and words[0] in SHEETS and words[1:] in ([], ["landscape"]):
        w, h = SHEETS[words[0]]
        name = {"a4": "A4", "a3": "A3", "letter": "Letter"}[words[0]]
        return ((h, w), f"{name} landscape", False) if words[1:] else ((w, h), name, True)
    match = re.fullmatch(r"\s*\[?\s*([^,\[\]\s]+)\s*[,x ]\s*([^,\[\]\s]+)\s*\]?\s*", text)
    size = None
    if match:
        try:
            size = (float(match[1]), float(match[2]))
        except ValueError:
            size = None
    if size is None:
        raise FoldfabError(f"{option} {text!r}: expected A4, A3, Letter (optionally followed by landscape) "
                           "or [width, height] in mm, such as \"[210, 297]\"")
    if not all(math.isfinite(v) and PAPER_MIN <= v <= PAPER_MAX for v in size):
        raise FoldfabError(f"{option} {text!r}: each side must be from {PAPER_MIN:g} to {PAPER_MAX:g} mm")
    return size, f"{size[0]:g} x {size[1]:g} mm", False


def check_options(options: PrintOptions) -> None:
    """Refuse margins and overlaps that leave no room for the pattern, naming the option."""
    w, h = options.paper
    if not (math.isfinite(options.margin) and 0 <= options.margin <= MARGIN_MAX):
        raise FoldfabError(f"--margin {options.margin:g}: expected a number of mm from 0 to {MARGIN_MAX:g}")
    if not (math.isfinite(options.overlap) and 0 <= options.overlap <= OVERLAP_MAX):
        raise FoldfabError(f"--overlap {options.overlap:g}: expected a number of mm from 0 to {OVERLAP_MAX:g}")
    width, height = min(w, h) - 2 * options.margin, min(w, h) - 2 * options.margin - HEADER - FOOTER
    if width < MIN_AREA[0] or height < MIN_AREA[1]:
        raise FoldfabError(f"--margin {options.margin:g}: leaves less than {MIN_AREA[0]:g} x {MIN_AREA[1]:g} mm of the "
                           f"{w:g} x {h:g} mm paper for the pattern and the scale bar; use a smaller margin or "
                           "larger --paper")
    if not (math.isfinite(options.scale) and options.scale > 0):
        raise FoldfabError(f"--scale {options.scale:g}: expected a number > 0")
