"""GP-GL writer for Graphtec cutters in their native language and Silhouette cutters.

Every command ends with ``\\x03`` (ETX); coordinates are whole device units (Silhouette: 20
per mm), the first along device x, the second along device y (on a Silhouette, x runs with
the feed, down the sheet, and y across it).  The program is:

* ``ESC 0x04`` (initialise), ``FN0`` and ``TB50,0`` (portrait orientation), ``\\0,0`` and
  ``Z x,y`` (the write area: the plottable area), as Silhouette Studio sends them;
* per sweep, only when they change: ``J t`` (tool holder, on carriages with more than one),
  ``FX f`` (force), ``! s`` (speed in whole cm/s) and, the first time a tool is used, ``FC p``
  (its blade offset in device units).  On a carriage with several holders each setting names
  its holder (``FX f,t``, ``! s,t``, ``FC p,1,t``, the Cameo 4's forms);
* each line as ``M x,y`` (tool up to its start), ``D x,y`` at the same point (tool down there:
  a line of one point is a dot) and one ``D x,y`` per further point;
* ``M x,y`` to the park position at a pause and at the end.

GP-GL has no pause command: as in HP-GL, pauses are byte offsets in
:attr:`~foldfab.programs.program.Program.pauses`.  Sources: ``devices/README.md``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from foldfab.programs.program import Program, ProgramBuilder, Sink, Stop, fmt_number, sweeps

if TYPE_CHECKING:
    from foldfab.devices import DeviceProfile
    from foldfab.fabrication.plan import PlotPlan

ETX = "\x03"
INITIALISE = "\x1b\x04"
STATUS = "\x1b\x05"


def write_gpgl(plan: PlotPlan, device: DeviceProfile, sink: Sink | None = None) -> Program:
    """The GP-GL program drawing ``plan`` on ``device``;
    ``sink``: see :class:`~foldfab.programs.program.ProgramBuilder` (the text streamed, not kept)."""
    import numpy as np

    items = sweeps(plan, device)
    out = ProgramBuilder("gpgl", device, sink=sink)
    park = "M{},{}".format(*device.park_units) + ETX
    holders = device.gpgl.tools
    width, height = (round(v * device.units_per_mm) for v in device.plottable_area)
    out.write(f"{INITIALISE}FN0{ETX}TB50,0{ETX}\\0,0{ETX}Z{width},{height}{ETX}")
    tool = force = speed = None
    offsets_set: set[int] = set()
    for item in items:
        if isinstance(item, Stop):
            out.write(park)
            out.pause(item)
            continue
        out.start(item)
        settings = item.tool
        suffix = f",{settings.pen}" if holders > 1 else ""
        if settings.pen != tool:
            if holders > 1:
                out.write(f"J{settings.pen}{ETX}")
            tool, force, speed = settings.pen, None, None
        if settings.force is not None and settings.force != force:
            out.write(f"FX{fmt_number(settings.force, 0)}{suffix}{ETX}")
            force = settings.force
        if settings.speed != speed:
            out.write(f"!{fmt_number(settings.speed / 10, 0)}{suffix}{ETX}")
            speed = settings.speed
        if settings.pen not in offsets_set:
            offset = round(device.gpgl.blade_offset[settings.pen - 1] * device.units_per_mm)
            out.write(f"FC{offset},1,{settings.pen}{ETX}" if holders > 1 else f"FC{offset}{ETX}")
            offsets_set.add(settings.pen)
        units = np.rint(item.points).astype(np.int64).ravel().tolist()
        start = 0
        for end in (2 * np.cumsum(item.sizes)).tolist():
            pairs = [f"{x},{y}" for x, y in zip(units[start:end:2], units[start + 1:end:2])]
            out.write(f"M{pairs[0]}{ETX}D" + f"{ETX}D".join(pairs) + ETX)
            start = end
    out.write(park)
    return out.build()
