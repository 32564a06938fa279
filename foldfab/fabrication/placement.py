"""Placing a design on the sheet: scale, rotate by 90 degrees to fit, centre, check the fit.

Crease-pattern millimetres (x right, y up) become sheet millimetres as the tool
sees them (origin at the sheet's top-left corner, y down).  A design that does
not fit the sheet (less its margins) or the device's plottable area is an error
that states both sizes and the largest scale that would fit: nothing is ever
cropped.  Pure geometry.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from foldfab.errors import FoldfabError


@dataclass(frozen=True)
class Placement:
    """An affine map from crease-pattern mm to sheet mm: p_sheet = origin + scale * R(p)."""

    scale: float
    rotated: bool
    origin: complex      # where the design's bounding-box corner lands
    lo: complex          # the design's bounding-box minimum corner (crease-pattern coordinates)
    size: tuple[float, float]   # placed width and height, mm

    def apply(self, points: np.ndarray) -> np.ndarray:
        """Map complex crease-pattern points to complex sheet points."""
        p = points - self.lo
        if self.rotated:   # 90 degrees: crease-pattern x runs down the sheet, y runs right
            x, y = p.imag, p.real
        else:              # y up in the crease pattern, y down on the sheet
            x, y = p.real, -p.imag
        out = self.scale * (x + 1j * y)
        return out + self.origin

    def invert(self, points: np.ndarray) -> np.ndarray:
        """Map complex sheet points back to complex crease-pattern points (:meth:`apply` undone):
        where the sheet's outline lies around the design, as the studio draws it."""
        q = (np.asarray(points) - self.origin) / self.scale
        return (q.imag + 1j * q.real if self.rotated else q.conj()) + self.lo


def usable(sheet: tuple[float, float], area: tuple[float, float, float, float], margin: float,
           reach: str = "the device's plottable area") -> tuple[float, float, float, float]:
    """The region a design may cover (x0, y0, x1, y1, sheet mm): the sheet less ``margin``,
    within the device ``area``; none at all is an error (``reach`` says what ``area`` is)."""
    x0, y0 = max(margin, area[0]), max(margin, area[1])
    x1, y1 = min(sheet[0] - margin, area[2]), min(sheet[1] - margin, area[3])
    if x1 <= x0 or y1 <= y0:
        raise FoldfabError(f"the sheet {sheet[0]:g} x {sheet[1]:g} mm with margin {margin:g} mm leaves no room inside "
                           f"{reach}; reduce [fabrication].margin or choose another sheet")
    return x0, y0, x1, y1


ROTATIONS = {"no": (False,), "yes": (True,), "auto": (False, True)}
"""The orientations ``rotate`` allows, in the order they are tried (unturned first)."""


def largest_scale(bounds: tuple[complex, complex], region: tuple[float, float, float, float],
                  rotate: str) -> float:
    """The largest scale at which the design's bounding box fits the :func:`usable` ``region``,
    turned or not as ``rotate`` allows: the smaller ratio of room to extent, of the better turn."""
    lo, hi = bounds
    w, h = hi.real - lo.real, hi.imag - lo.imag
    room = (region[2] - region[0], region[3] - region[1])

    def ratio(room_side: float, extent: float) -> float:
        return room_side / extent if extent > 0 else math.inf
    return max(min(ratio(room[0], h if rot else w), ratio(room[1], w if rot else h)) for rot in ROTATIONS[rotate])


def fit(bounds: tuple[complex, complex], sheet: tuple[float, float], area: tuple[float, float, float, float],
        margin: float, scale: float, rotate: str, reach: str = "the device's plottable area") -> Placement:
    """Centre the design in the usable region: the sheet less ``margin``, within the device ``area`` (x0, y0, x1, y1).

    ``rotate`` is "auto" (turn by 90 degrees only when that is needed to fit), "yes" or "no";
    ``reach`` says what ``area`` is, for the errors.
    """
    lo, hi = bounds
    w, h = hi.real - lo.real, hi.imag - lo.imag
    x0, y0, x1, y1 = region = usable(sheet, area, margin, reach)
    room = (x1 - x0, y1 - y0)

    def fits(rot: bool) -> bool:
        pw, ph = (h, w) if rot else (w, h)
        return scale * pw <= room[0] + 1e-9 and scale * ph <= room[1] + 1e-9

    chosen = next((rot for rot in ROTATIONS[rotate] if fits(rot)), None)
    if chosen is None:
        best = math.floor(largest_scale(bounds, region, rotate) * 1e4) / 1e4  # rounded down: it does fit
        raise FoldfabError(
            f"the design is {w * scale:.1f} x {h * scale:.1f} mm at scale {scale:g}, but only {room[0]:.1f} x {room[1]:.1f} mm "
            f"is usable (sheet {sheet[0]:g} x {sheet[1]:g} mm less {margin:g} mm margins, within {reach}); "
            f"the largest scale that fits is {best:.4f}{'' if rotate != 'no' else ' (rotation is off)'}: "
            f"use --scale fit or [fabrication].scale = \"fit\" (or that number), a larger sheet, or a smaller margin")
    pw, ph = ((h, w) if chosen else (w, h))
    pw, ph = pw * scale, ph * scale
    corner = complex(x0 + (room[0] - pw) / 2, y0 + (room[1] - ph) / 2)
    # The bounding-box minimum of the rotated/flipped design lands on the corner.
    origin = corner if chosen else corner + 1j * ph
    return Placement(scale, chosen, origin, lo, (pw, ph))


def mirror(points: np.ndarray, sheet_width: float) -> np.ndarray:
    """Where front-side points lie when the sheet is flipped about its left-right axis (x -> W - x)."""
    return (sheet_width - points.real) + 1j * points.imag
