"""The plot plan: what to draw, in which order, with which tool.

A :class:`PlotPlan` is the hand-over point between the geometry half of foldfab
(crease pattern, placement) and the device half (program writers, interpreters,
estimates, previews).  Coordinates are millimetres on the sheet as the tool sees
it: origin at the sheet's top-left corner, x to the right, y down (the vpype/SVG
orientation).  Device writers map them to plotter coordinates.

This module is imported by the command line's fast path: it must not import
vpype or numpy at module level.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Union

from foldfab.devices import Blade, Tool

if TYPE_CHECKING:
    import numpy
    import vpype


@dataclass(frozen=True)
class Pass:
    """Draw every line of one document layer with one tool."""

    layer_id: int
    """Key in ``PlotPlan.document.layers``."""
    name: str
    """"valley", "mountain", "cut" or any other layer name."""
    tool: Tool
    blade: Blade | None = None
    """The drag-knife compensation :func:`foldfab.fabrication.layout.finish_plan` applies to the
    layer's lines once their order and direction are final; None: the lines as they are."""


@dataclass(frozen=True)
class Pause:
    """Stop and let the operator act (flip the sheet, change the tool...).  Every device
    parks the pen there, so the pen-up travel there and back is part of the plot."""

    message: str


Step = Union[Pass, Pause]


@dataclass
class PlotPlan:
    """Layers to draw, the ordered steps that draw them, and the sheet they lie on."""

    document: vpype.Document
    """Lines in millimetres on the sheet as seen by the tool (origin top-left, y down)."""
    steps: list[Step]
    """Executed in this order; writers never reorder across steps."""
    sheet: tuple[float, float]
    """Sheet width and height in mm."""


def device_steps(plan: PlotPlan, tool_changer: bool) -> Iterator[tuple[int, Step]]:
    """The plan's steps as a device runs them, each with its index in ``plan.steps``.

    A device without a tool changer (``tool_changer`` false) must stop for the operator
    before a pass that draws with another tool than the last pass that drew anything: a
    :class:`Pause` saying so comes first, with the index of that pass.  The program writers
    and the travel optimizer both take the steps from here, so that they park the pen at
    the same places.
    """
    pen = None
    for index, step in enumerate(plan.steps):
        if isinstance(step, Pass) and any(len(line) for line in plan.document.layers.get(step.layer_id, ())):
            if pen is not None and step.tool.pen != pen and not tool_changer:
                yield index, Pause(f"Load tool {step.tool.pen} for the {step.name} pass, then resume.")
            pen = step.tool.pen
        yield index, step


def collection(lines: list[numpy.ndarray]) -> vpype.LineCollection:
    """``lines`` (1-D complex arrays of two points or more) as a vpype ``LineCollection`` that
    holds these very arrays: its constructor copies each line in a Python call of its own,
    a third of a second for a hundred thousand lines.  The arrays may be views into one
    array, or into another plan's lines (the optimizer's orders are the lay-out's lines, some
    seen backwards), since nothing in foldfab changes a plan's lines in place."""
    import vpype as vp

    layer = vp.LineCollection()
    layer.lines.extend(lines)  # vpype's documented list of the collection's lines, itself
    return layer
