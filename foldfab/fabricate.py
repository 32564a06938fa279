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
