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
    import numpy as np

    from foldfab.devices import DeviceProfile
    from foldfab.fabrication.plan import PlotPlan

SPEED_DECIMALS = {"hp": 2, "graphtec": 0, "roland": 0}
BATCH = 1 << 13
"""Strokes turned into text at once (a few hundred kilobytes of it)."""


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
        for units, sizes in item.batches(rounded, BATCH):
            _write_strokes(out, units, sizes, limit, device)
    out.write(park)
    out.recorder.move(device.park_units)
    return out.build()


def _write_strokes(out: ProgramBuilder, units: np.ndarray, sizes: np.ndarray, limit: int,
                   device: DeviceProfile) -> None:
    """Strokes of ``sizes`` points, their whole plotter ``units`` (M, 2) one after another, each as
    ``PUx,y;PDx,y,...;``: a batch's coordinates turned into text at once, the strokes whose ``PD``
    list is too long for one instruction (:func:`_split_pd`) one by one."""
    import numpy as np

    texts = list(map(str, units.ravel().tolist()))
    widths = np.fromiter(map(len, texts), dtype=np.int64, count=len(texts))
    ends = np.cumsum(sizes)
    firsts = ends - sizes
    digits = np.add.reduceat(widths, 2 * firsts) if len(sizes) else widths[:0]   # per stroke
    pd_bytes = digits - widths[2 * firsts] - widths[2 * firsts + 1] + np.maximum(2 * sizes - 3, 0) + 3
    done = 0
    for long in [*np.flatnonzero(pd_bytes > limit).tolist(), len(sizes)]:
        if done < long:
            _write_short(out, texts[2 * firsts[done]:2 * ends[long - 1]], sizes[done:long], digits[done:long])
        if long < len(sizes):
            pair = texts[2 * firsts[long]:2 * ends[long]]
            out.write(f"PU{pair[0]},{pair[1]};PD{_split_pd(pair[2:], limit, device)};")
            out.recorder.ended(out.offset)  # the next command lifts the pen
        done = long + 1


def _write_short(out: ProgramBuilder, texts: list[str], sizes: np.ndarray, digits: np.ndarray) -> None:
    """Strokes whose ``PD`` list fits one instruction, their coordinates' ``texts`` (x, y, x, y,
    ...) one after another, ``digits`` their bytes per stroke: ``PUx,y;PDx,y,...;`` each, as one
    join over coordinates and separators (a dot is ``PUx,y;PD;``)."""
    import numpy as np

    firsts = np.cumsum(sizes) - sizes
    lines = sizes > 1
    separators = np.full(len(texts) + 1, ",", dtype=object)   # before each coordinate, and the end
    separators[2 * firsts[1:]] = np.where(lines[:-1], ";PU", ";PD;PU")   # the stroke before ends
    separators[0] = "PU"
    separators[2 * firsts[lines] + 2] = ";PD"
    separators[-1] = ";" if lines[-1] else ";PD;"
    joined = np.empty(2 * len(texts) + 1, dtype=object)
    joined[0::2] = separators
    joined[1::2] = texts
    lengths = digits + np.where(lines, 2 * sizes + 4, 7)   # "PU" "," ";PD" ",".. ";"; a dot: "PU" "," ";PD;"
    out.recorder.ends(out.offset + np.cumsum(lengths))   # each at the command that lifts the pen
    out.write("".join(joined.tolist()))


def _split_pd(texts: list[str], limit: int, device: DeviceProfile) -> str:
    """The coordinates' ``texts`` (x, y, x, y, ...) as ``PD`` parameter lists joined by ``;PD``,
    each instruction at most ``limit`` bytes, filled greedily pair by pair (the pairs are
    independent, so the strokes drawn are the same)."""
    import numpy as np

    pairs = [f"{x},{y}" for x, y in zip(texts[::2], texts[1::2])]
    taken = np.concatenate([[0], np.cumsum(np.fromiter(map(len, pairs), dtype=np.int64, count=len(pairs)) + 1)])
    pieces: list[str] = []
    first = 0
    while first < len(pairs):
        # "PD", the pairs and a comma between two of them, ";": pairs first..last - 1 fit while
        # taken[last] - taken[first] + 2 <= limit (at least one pair, which must fit alone)
        last = max(int(np.searchsorted(taken, taken[first] + limit - 2, side="right")) - 1, first + 1)
        if len(pairs[first]) + 3 > limit:
            need = len(pairs[first]) + 3
            raise FoldfabError(
                f"{device.name}: a {device.buffer.size}-byte buffer ([buffer] size) holds HP-GL "
                f"instructions of at most {limit} bytes, too few for PD{pairs[first]}; ({need} bytes): "
                f"set [buffer] size to at least {need + 3 if need <= 24 else 2 * need}")
        pieces.append(",".join(pairs[first:last]))
        first = last
    return ";PD".join(pieces)
