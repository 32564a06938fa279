"""HPGL writer for HP pen plotters and Graphtec / Roland cutters in HP-GL mode.

Output is compact and deterministic: ``IN;`` first; per sweep ``SP``/``FS``/``VS`` only
when they change; each line as ``PU x,y;PD x,y,x,y,...;`` in integer plotter units,
the ``PD`` list split into several ``PD`` instructions where it would be longer than the
device's buffer allows (:attr:`~foldfab.devices.BufferSettings.instruction_limit`: a
sender can only ever send whole instructions, and one that never fits deadlocks it);
at a pause and at the end the pen is lifted, moved to the park position and put
away (``PU x,y;SP0;``).  HPGL has no pause command: pauses are byte offsets in
:attr:`Program.pauses` (see :mod:`foldfab.programs.program`).  Speeds are sent as ``VS`` in
cm/s (two decimals for ``hp``, whole cm/s for ``graphtec`` and ``roland``); forces as
``FS`` in the device's own unit (Graphtec force steps, Roland grams-force).

vpype's ``write_hpgl`` is not used: it sets one velocity for the whole file, has no
force and no pauses, and crops geometry outside the plotter's range silently.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from foldfab.errors import FoldfabError
from foldfab.programs.program import Program, ProgramBuilder, Sink, Stop, fmt_number, sweeps

if TYPE_CHECKING:
    from foldfab.devices import DeviceProfile
    from foldfab.fabrication.plan import PlotPlan

SPEED_DECIMALS = {"hp": 2, "graphtec": 0, "roland": 0}


def write_hpgl(plan: PlotPlan, device: DeviceProfile, sink: Sink | None = None) -> Program:
    """The HPGL program drawing ``plan`` on ``device``;
    ``sink``: see :class:`~foldfab.programs.program.ProgramBuilder` (the text streamed, not kept)."""
    import numpy as np

    items = sweeps(plan, device)
    out = ProgramBuilder("hpgl", device, record=True, sink=sink)
    park_x, park_y = device.park_units
    park = f"PU{park_x},{park_y};SP0;"
    limit = device.buffer.instruction_limit
    out.write("IN;")
    pen = force = speed = None
    for item in items:
        if isinstance(item, Stop):
            out.write(park)
            out.recorder.move(device.park_units)
            pen = 0
            out.pause(item)
            continue
        out.start(item)
        tool = item.tool
        if tool.pen != pen:
            out.write(f"SP{tool.pen};")
            pen = tool.pen
        if tool.force is not None and tool.force != force:
            out.write(f"FS{fmt_number(tool.force, 0)};")
            force = tool.force
        velocity = fmt_number(tool.speed / 10, SPEED_DECIMALS[device.dialect])
        if tool.speed != speed:
            out.write(f"VS{velocity};")
            speed = tool.speed
        rounded = np.rint(item.points).astype(np.int64)
        out.recorder.strokes(rounded, item.sizes, float(velocity) * 10, item.name)
        for units, sizes in item.batches(rounded):   # one conversion to Python ints per batch, then slices
            units = units.ravel().tolist()
            start = 0
            for end in (2 * np.cumsum(sizes)).tolist():
                rest = ",".join(map(str, units[start + 2:end]))
                if len(rest) + 3 > limit:
                    rest = _split_pd(units[start + 2:end], limit, device)
                out.write(f"PU{units[start]},{units[start + 1]};PD{rest};")
                out.recorder.ended(out.offset)  # the next command lifts the pen
                start = end
    out.write(park)
    out.recorder.move(device.park_units)
    return out.build()


def _split_pd(units: list[int], limit: int, device: DeviceProfile) -> str:
    """The coordinates ``units`` (x, y, x, y, ...) as ``PD`` parameter lists joined by ``;PD``,
    each instruction at most ``limit`` bytes (the pairs are independent, so the strokes
    drawn are the same)."""
    pieces: list[str] = []
    used = 0  # bytes of the instruction being filled, "PD" and commas included
    for pair in map("{},{}".format, units[::2], units[1::2]):
        if used and used + 1 + len(pair) + 1 > limit:
            pieces.append(";PD")
            used = 0
        if used:
            pieces.append(",")
        elif len(pair) + 3 > limit:
            need = len(pair) + 3
            raise FoldfabError(
                f"{device.name}: a {device.buffer.size}-byte buffer ([buffer] size) holds HP-GL "
                f"instructions of at most {limit} bytes, too few for PD{pair}; ({need} bytes): "
                f"set [buffer] size to at least {need + 3 if need <= 24 else 2 * need}")
        pieces.append(pair)
        used += len(pair) + (1 if used else 2)
    return "".join(pieces)
