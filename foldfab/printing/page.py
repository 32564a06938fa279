"""A page of a template as drawing primitives in page millimetres (origin at the bottom-left
corner, y up), so that the PDF and the SVG renderers draw the same thing."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Lines:
    """Polylines sharing one style; ``clip`` (x0, y0, x1, y1) hides what lies outside."""

    polylines: list[np.ndarray]           # each (n, 2) page mm
    color: str
    width: float
    dash: tuple[float, ...] = ()
    clip: tuple[float, float, float, float] | None = None


@dataclass(frozen=True)
class Shape:
    """A closed polygon, filled and/or outlined."""

    points: np.ndarray                    # (n, 2) page mm
    fill: str | None = None
    stroke: str | None = None
    width: float = 0.2


@dataclass(frozen=True)
class Text:
    """One line of text: ``size`` in points, ``anchor`` start, middle or end at (x, y)."""

    x: float
    y: float
    text: str
    size: float = 8.0
    anchor: str = "start"
    bold: bool = False


@dataclass
class Page:
    """One printed page: its size in mm and what is drawn on it, in order."""

    width: float
    height: float
    items: list[Lines | Shape | Text] = field(default_factory=list)


def rect(x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
    """The corners of an axis-aligned rectangle, counter-clockwise."""
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], float)
