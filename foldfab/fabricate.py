"""Design to program for one device: the one entry point the command line and the studio call.

:func:`fabricate` reads the job's ``[fabrication]`` table, lays the design out as a plot plan
(:mod:`foldfab.fabrication`) and writes it in the device's language (:mod:`foldfab.programs`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property
from typing import Any

from foldfab.design import Design
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
    program: Any            # foldfab.programs.program.Program
    design: Design
    device: DeviceProfile
    layout: PlotPlan        # the plan before optimization (for the travel it saves)
    warnings: tuple[str, ...] = ()   # job settings the device does not have, ignored
    piece: Any = None       # foldfab.geometry.split.Piece this sheet draws, None for a whole design

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

        if self.spec.optimize == "none":
            return self.travel_after
        unoptimized = finish_plan(self.layout, self.device, self.spec, optimize="none")
        return travel(unoptimized, park_position(self.device, self.plan.sheet), self.device.tool_changer)


def fabricate(design: Design, device: DeviceProfile, spec: FabricationSpec | None = None,
              scale: float | str | None = None) -> Fabrication:
    """Plan, optimize and write the program of ``design`` for ``device``; ``scale`` (a number
    or "fit", the command line's ``--scale``) replaces the job's ``[fabrication].scale``."""
    from foldfab.programs.languages import write_program

    if spec is None:
        spec = job_spec(design.job)
    if scale is not None:
        spec = replace(spec, scale=scale)
    placement, sheet = place(design, device, spec)
    tools, warnings = layer_tools(design, device, spec)
    layout = lay_out(design, device, spec, placement, sheet, tools)
    plan = finish_plan(layout, device, spec)
    return Fabrication(spec, placement, plan, write_program(plan, device), design, device, layout,
                       tuple(warnings))


def fabricate_sheets(design: Design, device: DeviceProfile, spec: FabricationSpec | None = None,
                     scale: float | str | None = None, split: str | None = None,
                     one_program: bool = False) -> list[Fabrication]:
    """:func:`fabricate` for every sheet: one fabrication per piece of a split design
    (:func:`~foldfab.fabrication.pieces.design_pieces`), the design whole when it is not split.
    ``split`` ("auto", the command line's ``--split``) replaces the job's ``[fabrication].split``;
    ``one_program`` gives one fabrication drawing every sheet in turn, with a pause before each
    new sheet ("Load sheet 2 of 3")."""
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
        return [fabricate(design, device, spec)]
    parts = [piece_design(design, piece) for piece in pieces]
    if spec.scale == "fit":   # one scale for all the pieces, or they would not glue together
        spec = replace(spec, scale=min(place(part, device, spec)[0].scale for part in parts))
    sheets = [replace(fabricate(part, device, spec), piece=piece) for piece, part in zip(pieces, parts)]
    return [_one_program(sheets, device, spec)] if one_program else sheets


def _one_program(sheets: list[Fabrication], device: DeviceProfile, spec: FabricationSpec) -> Fabrication:
    """The sheets' layouts as one plan, the operator asked to load each new sheet, then
    optimized and written as one program (sheet by sheet: a pause is never crossed)."""
    import vpype as vp

    from foldfab.fabrication.pieces import sheet_message
    from foldfab.fabrication.plan import Pass, Pause
    from foldfab.programs.languages import write_program

    doc = vp.Document()
    doc.page_size = sheets[0].layout.sheet
    steps: list = []
    for number, fab in enumerate(sheets, 1):
        if number > 1:
            steps.append(Pause(sheet_message(number, len(sheets))))
        base = 10 * number   # each sheet's layers get ids of their own
        for step in fab.layout.steps:
            if isinstance(step, Pass):
                doc.add(fab.layout.document.layers[step.layer_id], base + step.layer_id, with_metadata=True)
                step = Pass(base + step.layer_id, step.name, step.tool)
            steps.append(step)
    layout = PlotPlan(doc, steps, sheets[0].layout.sheet)
    plan = finish_plan(layout, device, spec)
    first = sheets[0]
    return Fabrication(spec, first.placement, plan, write_program(plan, device), first.design, device, layout,
                       first.warnings)
