"""Origami's line conventions as printed: valley folds dashed, mountain folds dash-dot, cut
lines solid, flat creases faint grey (drawn only when asked).

Colours are the Okabe-Ito palette (blue and vermillion stay apart for every common colour
vision deficiency), and every kind differs in its dash pattern too, so a page printed in
black and white or read by a colour-blind folder still tells them apart; ``mono`` draws
everything black.  Widths and dashes are in mm: 0.3 mm is 7 dots at 600 dpi, and dashes of
3 mm with 1.5 mm gaps stay distinct on a laser or ink-jet printer.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class LineStyle:
    """How one kind of line is drawn: colour, width and dash pattern (on, off, ... in mm;
    empty: solid)."""

    label: str
    color: str
    width: float
    dash: tuple[float, ...] = ()


STYLES = {
    "V": LineStyle("valley fold", "#0072b2", 0.3, (3.0, 1.5)),
    "M": LineStyle("mountain fold", "#d55e00", 0.3, (3.0, 1.0, 0.6, 1.0)),
    "B": LineStyle("cut", "#000000", 0.35),
    "F": LineStyle("flat crease (no fold)", "#b0b0b0", 0.15, (1.0, 1.0)),
}
"""Line styles by crease assignment (B: the border, cut)."""
MARKS = LineStyle("match marks (draw, do not cut)", "#000000", 0.2)
"""A split piece's number and its tabs' and edges' letters: thin and solid, in the cut's colour
as on the plotter's marks layer."""
MONO_GREY = "#909090"
"""The flat creases' colour in ``mono``: grey stays the one hint that they are not folded."""


def line_styles(mono: bool, flat: bool) -> dict[str, LineStyle]:
    """The styles the template draws, in legend order: valley, mountain, cut, and flat when
    ``flat``; all black (flat creases grey) when ``mono``."""
    kinds = ("V", "M", "B", "F") if flat else ("V", "M", "B")
    styles = {kind: STYLES[kind] for kind in kinds}
    if mono:
        styles = {kind: LineStyle(s.label, MONO_GREY if kind == "F" else "#000000", s.width, s.dash)
                  for kind, s in styles.items()}
    return styles
