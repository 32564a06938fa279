"""Design to program for one device: the one entry point the command line and the studio call.

:func:`fabricate` reads the job's ``[fabrication]`` table, lays the design out as a plot plan
(:mod:`foldfab.fabrication`) and writes it in the device's language (:mod:`foldfab.programs`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property
from typing import Any

from foldfab.design import Design
from foldfab.job import Job
from foldfab.devices import DeviceProfile
from foldfab.fabrication.layout import finish_plan, lay_out, layer_tools, park_position, place
from foldfab.fabrication.plan import PlotPlan
from foldfab.fabrication.spec import FabricationSpec, job_spec, placement_text


@dataclass(frozen=True)
class Fabrication:
    """A design made ready for one device: the plan, its program, and the travel it saves."""

    spec: FabricationSpec
    placement: Any          # foldfab.fabrication.placement.Placement: crease-pattern mm -> sheet mm (front side)
    plan: PlotPlan
    program: Any            # foldfab.programs.program.Program (None until written: see :func:`finish`)
    job: Job
    device: DeviceProfile
    layout: PlotPlan        # the plan before optimization (for the travel it saves)
    warnings: tuple[str, ...] = ()   # job settings the device does not have, ignored
    piece: Any = None       # foldfab.geometry.split.Piece this sheet draws, None for a whole design
    measured_before: dict | None = None   # travel_before, kept where the layout is not (without_layout)

    @property
    def placement_summary(self) -> str:
        """The scale the design is drawn at and whether it is turned (:func:`placement_text`)."""
        return placement_text(self.placement.scale, self.spec.scale == "fit", self.placement.rotated)

    @property
    def blade_notes(self) -> list[str]:
        """One line per pass whose lines are moved for a drag knife (:func:`blade_text`)."""
        from foldfab.fabrication.blade import blade_text
        from foldfab.fabrication.plan import Pass

        return [blade_text(step.name, step.blade) for step in self.plan.steps
                if isinstance(step, Pass) and step.blade is not None]

    @cached_property
    def travel_after(self) -> dict:
        """Pen-up travel of the plan (:func:`foldfab.fabrication.optimize.travel`)."""
        from foldfab.fabrication.optimize import travel

        return travel(self.plan, park_position(self.device, self.plan.sheet), self.device.tool_changer)

    @cached_property
    def travel_before(self) -> dict:
        """Pen-up travel of the same layers unoptimized (on demand: only reports need it)."""
        from foldfab.fabrication.optimize import travel

        if self.measured_before is not None:
            return self.measured_before
        if self.spec.optimize == "none":
            return self.travel_after
        unoptimized = finish_plan(self.layout, self.device, self.spec, optimize="none")
        return travel(unoptimized, park_position(self.device, self.plan.sheet), self.device.tool_changer)

    def without_layout(self) -> Fabrication:
        """The same fabrication without its layout (every stroke a second time, 200 MB for a
        million strokes), its :attr:`travel_before` measured first: for a caller that writes and
        reports a large program and needs nothing else of the layout."""
        return replace(self, layout=None, measured_before=self.travel_before)


@dataclass(frozen=True)
class LaidOut:
    """A design laid out for one device, not yet optimized: all that fabrication needs of the
    design, so that its crease pattern and mesh (a large design's biggest part) can go."""

    spec: FabricationSpec
    placement: Any          # foldfab.fabrication.placement.Placement
    layout: PlotPlan
    job: Job
    warnings: tuple[str, ...] = ()
    piece: Any = None       # foldfab.geometry.split.Piece this sheet draws, None for a whole design


def fabricate(design: Design, device: DeviceProfile, spec: FabricationSpec | None = None,
              scale: float | str | None = None) -> Fabrication:
    """Plan, optimize and write the program of ``design`` for ``device``; ``scale`` (a number
    or "fit", the command line's ``--scale``) replaces the job's ``[fabrication].scale``."""
    return finish(lay_out_design(design, device, spec, scale), device)


def lay_out_design(design: Design, device: DeviceProfile, spec: FabricationSpec | None = None,
                   scale: float | str | None = None) -> LaidOut:
    """The first half of :func:`fabricate`: ``design`` placed and laid out as plot layers."""
    if spec is None:
        spec = job_spec(design.job)
    if scale is not None:
        spec = replace(spec, scale=scale)
    placement, sheet = place(design, device, spec)
    tools, warnings = layer_tools(design, device, spec)
    layout = lay_out(design, device, spec, placement, sheet, tools)
    return LaidOut(spec, placement, layout, design.job, tuple(warnings))


def finish(laid: LaidOut, device: DeviceProfile, write: bool = True) -> Fabrication:
    """The second half of :func:`fabricate`: the layout optimized and, unless ``write`` is false
    (a caller that streams the program to a file writes it itself), written."""
    from foldfab.programs.languages import write_program

    plan = finish_plan(laid.layout, device, laid.spec)
    return Fabrication(laid.spec, laid.placement, plan, write_program(plan, device) if write else None, laid.job,
                       device, laid.layout, laid.warnings, laid.piece)


def fabricate_sheets(design: Design, device: DeviceProfile, spec: FabricationSpec | None = None,
                     scale: float | str | None = None, split: str | None = None,
                     one_program: bool = False) -> list[Fabrication]:
    """:func:`fabricate` for every sheet: one fabrication per piece of a split design
    (:func:`~foldfab.fabrication.pieces.design_pieces`), the design whole when it is not split.
    ``split`` ("auto", the command line's ``--split``) replaces the job's ``[fabrication].split``;
    ``one_program`` gives one fabrication drawing every sheet in turn, with a pause before each
    new sheet ("Load sheet 2 of 3")."""
    return finish_sheets(lay_out_sheets(design, device, spec, scale, split), device, one_program)


def lay_out_sheets(design: Design, device: DeviceProfile, spec: FabricationSpec | None = None,
                   scale: float | str | None = None, split: str | None = None) -> list[LaidOut]:
    """The first half of :func:`fabricate_sheets`: each sheet laid out (:func:`lay_out_design`)."""
    from foldfab.fabrication.layout import reachable
    from foldfab.fabrication.pieces import design_pieces, piece_design

    if spec is None:
        spec = job_spec(design.job)
    if scale is not None:
        spec = replace(spec, scale=scale)
    if split is not None:
        spec = replace(spec, split=split)
    sheet, area, reach = reachable(design, device, spec)
    pieces = design_pieces(design, spec, sheet, area, reach)
    if not pieces:
        return [lay_out_design(design, device, spec)]
    parts = [piece_design(design, piece) for piece in pieces]
    if spec.scale == "fit":   # one scale for all the pieces, or they would not glue together
        spec = replace(spec, scale=min(place(part, device, spec)[0].scale for part in parts))
    return [replace(lay_out_design(part, device, spec), piece=piece) for piece, part in zip(pieces, parts)]


def finish_sheets(sheets: list[LaidOut], device: DeviceProfile, one_program: bool = False,
                  write: bool = True) -> list[Fabrication]:
    """The second half of :func:`fabricate_sheets` (``write`` as for :func:`finish`)."""
    if one_program and sheets[0].piece is not None:
        return [_one_program(sheets, device, write)]
    return [finish(laid, device, write) for laid in sheets]


def _one_program(sheets: list[LaidOut], device: DeviceProfile, write: bool) -> Fabrication:
    """The sheets' layouts as one plan, the operator asked to load each new sheet, then
    optimized and written as one program (sheet by sheet: a pause is never crossed)."""
    import vpype as vp

    from foldfab.fabrication.pieces import sheet_message
    from foldfab.fabrication.plan import Pass, Pause

    doc = vp.Document()
    doc.page_size = sheets[0].layout.sheet
    steps: list = []
    for number, laid in enumerate(sheets, 1):
        if number > 1:
            steps.append(Pause(sheet_message(number, len(sheets))))
        base = 10 * number   # each sheet's layers get ids of their own
        for step in laid.layout.steps:
            if isinstance(step, Pass):
                doc.add(laid.layout.document.layers[step.layer_id], base + step.layer_id, with_metadata=True)
                step = Pass(base + step.layer_id, step.name, step.tool)
            steps.append(step)
    first = sheets[0]
    return finish(LaidOut(first.spec, first.placement, PlotPlan(doc, steps, first.layout.sheet), first.job,
                          first.warnings), device, write)
