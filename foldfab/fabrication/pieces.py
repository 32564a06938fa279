"""A design too large for its sheet, split into pieces that each fit (``[fabrication] split``).

:func:`design_pieces` chooses or takes the cuts and builds the pieces
(:mod:`foldfab.geometry.split`); :func:`piece_design` makes a piece a design of its own, so
that every output (files, plans, programs, previews) handles a piece as it handles a design.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

from foldfab.design import Design
from foldfab.errors import DesignError, FoldfabError
from foldfab.fabrication.spec import FabricationSpec

if TYPE_CHECKING:
    from foldfab.geometry.split import Piece


def design_pieces(design: Design, spec: FabricationSpec, sheet: tuple[float, float] | None = None,
                  area: tuple[float, float, float, float] | None = None, reach: str = "the sheet") -> list[Piece]:
    """The pieces of ``design`` by ``spec.split`` and ``spec.split_height``; [] when it is not split.

    "auto" cuts into the fewest pieces that each fit ``sheet`` less ``spec.margin`` (within the
    device's ``area``) at ``spec.scale``, turned as ``spec.rotate`` allows; a design that fits
    whole, or one scaled to fit ("fit"), is not split."""
    if not spec.split and not spec.split_height:
        return []
    from foldfab.geometry.split import auto_cuts, split_pattern   # only here: most designs are not split

    job = design.job
    columns, rows = spec.split, list(spec.split_height)
    try:
        if columns == "auto":
            if spec.scale == "fit":
                return []
            if sheet is None:
                raise FoldfabError(f"{job.path}: [fabrication].split = \"auto\" fits pieces to the sheet: set "
                                   "[fabrication].sheet (this command has no --device)")
            columns, rows = auto_cuts(design.grid, job.crease.glue_tab, _fits(spec, sheet, area, reach),
                                      rows or None)
        pieces = split_pattern(design.grid, job.crease.flat_angle, job.crease.glue_tab, list(columns), rows)
    except DesignError as exc:
        raise DesignError(f"{job.path}: {exc}") from None
    return pieces if len(pieces) > 1 else []


def _fits(spec: FabricationSpec, sheet: tuple[float, float], area, reach: str):
    """Whether a piece ``width`` x ``height`` mm fits the usable part of the sheet at the spec's scale."""
    from foldfab.fabrication.placement import largest_scale, usable

    region = usable(sheet, area or (0.0, 0.0, *sheet), spec.margin, reach)
    return lambda width, height: largest_scale((0j, complex(width, height)), region, spec.rotate) >= spec.scale


def piece_design(design: Design, piece: Piece) -> Design:
    """``piece`` as a design of its own: its crease pattern and match marks, the same job and model."""
    return replace(design, crease_pattern=piece.crease_pattern, marks=piece.marks)


def sheet_message(number: int, count: int) -> str:
    """The operator's instruction between the sheets of a split design."""
    return f"Load sheet {number} of {count} (piece {number}), then continue."
