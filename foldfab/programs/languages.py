"""The device languages foldfab writes, by the protocol a device profile names.

One writer per language (:mod:`~foldfab.programs.hpgl`, :mod:`~foldfab.programs.gcode`,
:mod:`~foldfab.programs.gpgl`), each
building on the device-neutral :mod:`~foldfab.programs.program`; a new language is one module
and one entry here.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable

from foldfab.programs.ebb import write_ebb
from foldfab.programs.gcode import write_gcode
from foldfab.programs.gpgl import write_gpgl
from foldfab.programs.hpgl import write_hpgl

if TYPE_CHECKING:
    from foldfab.devices import DeviceProfile
    from foldfab.fabrication.plan import PlotPlan
    from foldfab.programs.program import Program, Sink

WRITERS: dict[str, Callable[..., Program]] = {"hpgl": write_hpgl, "gcode": write_gcode,
                                                                       "ebb": write_ebb, "gpgl": write_gpgl}
"""The program writer of each protocol (``DeviceProfile.protocol``)."""


def write_program(plan: PlotPlan, device: DeviceProfile, sink: Sink | None = None) -> Program:
    """Write ``plan`` in the device's language (HP-GL, G-code, EBB or GP-GL); ``sink`` (e.g. a
    file's ``write``) takes the text a block at a time as it is made, and the program keeps
    none (:attr:`~foldfab.programs.program.Program.text` None): the same bytes, never whole in memory."""
    return WRITERS[device.protocol](plan, device, sink)
