"""Plotter programs: the text a device receives, plus what foldfab knows about it.

A :class:`Program` is the exact text to send (ASCII; byte offsets = character
offsets) together with two lists a streaming sender and the interpreters need:

* ``pauses``: where the operator must act.  ``offset`` is the number of bytes that
  must have been sent *and executed* first.  HPGL has no pause command, so the HPGL
  text only parks the pen there (``PU x,y;SP0;``) and the sender must stop sending at
  ``offset``, wait until the plotter's buffer has drained, and prompt the operator.
  G-code contains a real ``M0`` ending exactly at ``offset`` (GRBL holds there itself;
  ``~`` resumes), preceded by the message as ``(comment)`` lines.
* ``sections``: which plan step, layer, repetition and tool each part of the text
  draws, starting at ``offset``.  The interpreters use them to label strokes.

Both writers share :func:`sweeps`, which validates the plan against the device,
converts coordinates, refuses designs outside the reachable area (never crops),
expands ``passes`` and inserts tool-change pauses for devices without a pen changer
(:func:`foldfab.fabrication.plan.device_steps`).
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field
from operator import attrgetter
from typing import TYPE_CHECKING, Callable, Union

from foldfab.errors import FoldfabError
from foldfab.devices import Tool
from foldfab.fabrication.plan import Pass, Pause, PlotPlan, device_steps
from foldfab.programs.drawing import Recorder, Recording

if TYPE_CHECKING:
    import numpy as np

    from foldfab.devices import DeviceProfile, Frame
    from foldfab.programs.drawing import Drawn


BLOCK = 1 << 16
"""Bytes of text from which :class:`ProgramBuilder` joins what it holds (and hands it to its sink)."""
Sink = Callable[[bytes], object]
"""Where a streaming writer puts its text, a block of ASCII bytes at a time (a file's ``write``)."""


@dataclass(frozen=True)
class Section:
    """One sweep over a layer: plan step ``step``, repetition ``repeat`` (0-based)."""

    offset: int
    step: int
    layer_id: int
    name: str
    repeat: int
    tool: Tool


@dataclass(frozen=True)
class PauseMark:
    """The operator must act once the first ``offset`` bytes have been executed."""

    offset: int
    step: int
    message: str


@dataclass(frozen=True)
class Program:
    """The exact program text for one device, with its sections and pauses."""

    text: str | None
    """None where the writer streamed the text to a file instead (:class:`ProgramBuilder`'s
    ``sink``): a million strokes' text is tens of megabytes, twice over as bytes."""
    protocol: str
    device: str
    sections: tuple[Section, ...]
    pauses: tuple[PauseMark, ...]
    recording: Recording | None = field(default=None, compare=False, repr=False)
    """What the writer drew, as it wrote it (HP-GL and G-code writers record; None otherwise)."""
    size: int = field(default=-1, compare=False)
    """Bytes of the program: its text's length, or as given where the text was streamed."""

    def __post_init__(self) -> None:
        if self.text is not None:
            object.__setattr__(self, "size", len(self.text))

    def drawn(self, frame: Frame) -> Drawn | None:
        """What the program draws on the sheet ``frame`` maps to, as its writer recorded it (no
        read-back); None when the writer did not record."""
        if self.recording is None:
            return None
        return self.recording.drawn(frame, tuple(p.message for p in self.pauses))

    def encode(self) -> bytes:
        """The bytes to send."""
        return self.text.encode("ascii")

    def section_at(self, offset: int) -> Section | None:
        """The section containing byte ``offset``, or None before the first one."""
        index = bisect.bisect_right(self.sections, offset, key=attrgetter("offset")) - 1
        return self.sections[index] if index >= 0 else None


@dataclass(frozen=True)
class Sweep:
    """Draw a layer's lines once with ``tool``: ``points`` (M, 2; device units, float) holds
    them one after another, line k ``sizes[k]`` points long (at least one)."""

    step: int
    layer_id: int
    name: str
    repeat: int
    tool: Tool
    points: np.ndarray
    sizes: np.ndarray

    def batches(self, points: np.ndarray | None = None, count: int = 1 << 16):
        """The lines ``count`` at a time: (their rows of ``points``, default :attr:`points`, and
        each line's size), for writers that turn points into text (a Python object per
        coordinate of a whole sweep would cost gigabytes)."""
        import numpy as np

        points = self.points if points is None else points
        ends = np.cumsum(self.sizes)
        for first in range(0, len(self.sizes), count):
            last = min(first + count, len(self.sizes))
            yield points[ends[first] - self.sizes[first]:ends[last - 1]], self.sizes[first:last]

    @property
    def lines(self) -> list[np.ndarray]:
        """Each line on its own (N, 2): for writers that work line by line anyway."""
        import numpy as np

        return np.split(self.points, np.cumsum(self.sizes)[:-1]) if len(self.sizes) else []


@dataclass(frozen=True)
class Stop:
    """Park and let the operator act."""

    step: int
    message: str


class ProgramBuilder:
    """Accumulates program text and records section and pause offsets."""

    def __init__(self, protocol: str, device: DeviceProfile, record: bool = False,
                 sink: Sink | None = None):
        self.protocol, self.device, self.sink = protocol, device, sink
        """``sink``: where the text goes a block at a time as it is made (e.g. a file's ``write``),
        instead of being kept: the program then has no :attr:`Program.text`."""
        self.recorder = Recorder(device.park_units) if record else None
        """Where the writer says what it draws (``record``: see :mod:`~foldfab.programs.drawing`)."""
        self.chunks: list[str] = []
        self.blocks: list[str] = []
        """Chunks joined a thousand (or :data:`BLOCK` bytes) at a time: a string per stroke costs
        its object header again."""
        self.pending = 0
        self.offset = 0
        self.sections: list[Section] = []
        self.pauses: list[PauseMark] = []

    def write(self, text: str) -> None:
        if self.pending and self.pending + len(text) > BLOCK:   # a block is at most BLOCK bytes or one write
            self._flush()
        self.chunks.append(text)
        self.offset += len(text)
        self.pending += len(text)
        if len(self.chunks) >= 1024 or self.pending >= BLOCK:
            self._flush()

    def _flush(self) -> None:
        block = "".join(self.chunks)
        self.chunks, self.pending = [], 0
        if self.sink is None:
            self.blocks.append(block)
        else:
            self.sink(block.encode("ascii"))   # writers emit ASCII only; fail loudly otherwise

    def start(self, sweep: Sweep) -> None:
        self.sections.append(Section(self.offset, sweep.step, sweep.layer_id, sweep.name,
                                     sweep.repeat, sweep.tool))

    def pause(self, stop: Stop) -> None:
        self.pauses.append(PauseMark(self.offset, stop.step, stop.message))

    def build(self) -> Program:
        if self.sink is not None:
            self._flush()
            text = None
        else:
            text = "".join(self.blocks + self.chunks)
            text.encode("ascii")  # writers emit ASCII only; fail loudly otherwise
        return Program(text, self.protocol, self.device.name, tuple(self.sections),
                       tuple(self.pauses), self.recorder.record if self.recorder else None, self.offset)


def sweeps(plan: PlotPlan, device: DeviceProfile) -> list[Union[Sweep, Stop]]:
    """The plan as device-ready sweeps and stops, in plan order."""
    import numpy as np

    frame = device.frame(plan.sheet)
    layers: dict[int, tuple[np.ndarray, np.ndarray]] = {}   # sheet points (complex) and line sizes
    for index, step in enumerate(plan.steps):
        if isinstance(step, Pass) and step.layer_id not in plan.document.layers:
            raise FoldfabError(
                f"plan step {index + 1} ({step.name} pass) draws layer {step.layer_id}, which "
                f"the document does not have (layers: {sorted(plan.document.layers)})"
            )
        if isinstance(step, Pass):
            device.check_tool(step.tool, f"plan step {index + 1} ({step.name} pass)")
        if isinstance(step, Pass) and step.layer_id not in layers:
            layers[step.layer_id] = _layer_arrays(plan.document.layers[step.layer_id])
        elif not isinstance(step, (Pass, Pause)):
            raise FoldfabError(f"plan step {index + 1} is a {type(step).__name__}, "
                               "expected a Pass or a Pause")
    drawn = [points for points, _ in layers.values() if len(points)]
    if drawn:
        check_fits(np.concatenate(drawn), plan.sheet, device)
    converted = {lid: (frame.to_device(points), sizes) for lid, (points, sizes) in layers.items()}

    result: list[Union[Sweep, Stop]] = []
    for index, step in device_steps(plan, device.tool_changer):
        if isinstance(step, Pause):
            result.append(Stop(index, step.message))
        elif len(converted[step.layer_id][1]):
            result.extend(Sweep(index, step.layer_id, step.name, repeat, step.tool, *converted[step.layer_id])
                          for repeat in range(step.tool.passes))
    return result


def _layer_arrays(lines) -> tuple[np.ndarray, np.ndarray]:
    """A layer's non-empty lines as one complex array and each line's point count."""
    import numpy as np

    sizes = np.fromiter(map(len, lines), dtype=np.int64, count=len(lines))
    points = np.asarray(np.concatenate(lines) if len(lines) else [], dtype=complex)
    return points, sizes[sizes > 0]


def check_fits(points: np.ndarray, sheet: tuple[float, float], device: DeviceProfile) -> None:
    """Refuse points (sheet mm, complex) outside the sheet or the device's reach; never crop."""
    import numpy as np

    if not np.all(np.isfinite(points)):
        raise FoldfabError("the plot plan contains non-finite coordinates (NaN or infinity); "
                           "this is a bug in the geometry that produced it")
    width, height = sheet
    area_w, area_h = device.plottable_area
    ax0, ay0, ax1, ay1 = device.frame(sheet).device_rect_on_sheet(area_w, area_h)
    ux0, uy0, ux1, uy1 = max(ax0, 0.0), max(ay0, 0.0), min(ax1, width), min(ay1, height)
    x0, x1 = points.real.min(), points.real.max()
    y0, y1 = points.imag.min(), points.imag.max()
    eps = 1e-6
    if x0 >= ux0 - eps and x1 <= ux1 + eps and y0 >= uy0 - eps and y1 <= uy1 + eps:
        return
    design_w, design_h = x1 - x0, y1 - y0
    usable_w, usable_h = max(ux1 - ux0, 0.0), max(uy1 - uy0, 0.0)
    scales = [u / d for u, d in ((usable_w, design_w), (usable_h, design_h)) if d > 0]
    scale = min(scales) if scales else 0.0
    advice = ("scale it down" if scale < 1 else "it fits at scale 1: move it") + \
        " into that area, or use a larger device or sheet"
    raise FoldfabError(
        f"design is {design_w:.1f} x {design_h:.1f} mm (x {x0:.1f}..{x1:.1f}, "
        f"y {y0:.1f}..{y1:.1f} mm on the sheet) but {device.name} reaches only "
        f"x {ux0:.1f}..{ux1:.1f}, y {uy0:.1f}..{uy1:.1f} mm of the {width:g} x {height:g} mm "
        f"sheet (plottable area {area_w:g} x {area_h:g} mm); largest scale that fits: "
        f"{scale:.3f}; {advice}"
    )


def fmt_number(value: float, decimals: int) -> str:
    """Shortest decimal text for ``value`` rounded to ``decimals`` places ("-0" -> "0")."""
    text = "%.*f" % (decimals, value)
    if decimals:
        text = text.rstrip("0").rstrip(".")
    return "0" if text == "-0" else text
