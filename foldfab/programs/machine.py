"""What a program draws (:class:`Interpretation`: strokes, travels, pauses) and the :class:`Machine`
that records it: the bookkeeping every language's reader shares (position, pen state, strokes and
travels in device units, converted to sheet mm).

Device-neutral and language-neutral: the readers (:mod:`~foldfab.programs.read_hpgl`,
:mod:`~foldfab.programs.read_gcode`) subclass :class:`Machine`, and
:func:`~foldfab.programs.interpret.interpret` picks one by protocol.
"""

from __future__ import annotations

import math
from array import array
from dataclasses import dataclass, field
from collections.abc import Iterable
from itertools import chain
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np

    from foldfab.devices import DeviceProfile, Frame
    from foldfab.programs.drawing import Drawn
    from foldfab.programs.program import PauseMark, Program, Section

_CHUNK = 1 << 16
"""Bytes :meth:`Machine.run_tokens` tokenizes at a time (a chunk's commands are garbage once run)."""


@dataclass
class Stroke:
    """One pen-down polyline, in sheet mm, with the tool state the program set."""

    points: np.ndarray
    """(N, 2) sheet mm; N == 1 for a dot."""
    pen: int | None
    """HPGL ``SP`` pen; None for G-code (it names no tool)."""
    force: float | None
    speed: float
    """mm/s as the device executes it (VS or F), else the profile's draw speed."""
    pen_down: float | str | None
    """G-code: the Z height or servo command that lowered the tool."""
    offset: int
    """Byte offset of the command that lowered the pen."""
    section: Section | None = None
    """Plan step, layer and repetition, when interpreting a Program."""
    end: int = -1
    """Byte offset of the command that lifted the pen (the text length if none did): once
    the device has executed the bytes before it, the stroke is drawn (resume, progress)."""
    power: float | None = None
    """A laser's power while it drew the stroke, as a share of its full power (``S`` / ``$30``);
    None for other tools."""

    @property
    def length(self) -> float:
        import numpy as np

        return float(np.hypot(*np.diff(self.points, axis=0).T).sum())

    @property
    def layer(self) -> str:
        """The layer name, or "pen N" / "unknown" when the program came without sections."""
        if self.section is not None:
            return self.section.name
        return f"pen {self.pen}" if self.pen is not None else "unknown"


@dataclass
class Travel:
    """A pen-up move between two sheet points (mm)."""

    start: tuple[float, float]
    end: tuple[float, float]
    next_stroke: int
    """Index of the stroke this move leads to (== number of strokes for the final move)."""


@dataclass
class PauseEvent:
    """The device stops here for the operator."""

    message: str
    position: tuple[float, float]
    offset: int
    strokes_before: int


@dataclass
class Interpretation:
    """What a program draws, in order."""

    protocol: str
    strokes: list[Stroke] = field(default_factory=list)
    travels: list[Travel] = field(default_factory=list)
    pauses: list[PauseEvent] = field(default_factory=list)
    ignored: list[str] = field(default_factory=list)
    """Commands or words that draw nothing and were not understood (for diagnostics)."""

    @property
    def drawn_length(self) -> float:
        return sum(stroke.length for stroke in self.strokes)

    @property
    def travel_length(self) -> float:
        return sum(math.dist(t.start, t.end) for t in self.travels)

    @property
    def pen_downs(self) -> int:
        return len(self.strokes)


def from_interpretation(run: Interpretation) -> Drawn:
    """The arrays of a program read back."""
    import numpy as np

    from foldfab.programs.drawing import Drawn

    names: dict[str, int] = {}
    layers = np.array([names.setdefault(s.layer, len(names)) for s in run.strokes], dtype=np.intp)
    sizes = np.array([len(s.points) for s in run.strokes], dtype=np.intp)
    points = np.concatenate([s.points for s in run.strokes]) if run.strokes else np.zeros((0, 2))
    travels = np.array([(*t.start, *t.end) for t in run.travels], dtype=float).reshape(-1, 4)
    return Drawn(points, np.cumsum(sizes) - sizes, np.array([s.speed for s in run.strokes], dtype=float),
                 layers, tuple(names), travels, np.array([t.next_stroke for t in run.travels], dtype=np.intp),
                 tuple(p.message for p in run.pauses),
                 np.array([s.end for s in run.strokes], dtype=np.intp)
                 if all(s.end >= 0 for s in run.strokes) else None)


class Machine:
    """Shared bookkeeping: position, pen state, strokes, travels (in device units)."""

    def __init__(self, protocol: str, device: DeviceProfile, frame: Frame, known: Program | None):
        self.device, self.frame, self.known = device, frame, known
        self.result = Interpretation(protocol)
        self.position = (0.0, 0.0)
        self.stroke: list[tuple[float, float]] | None = None
        self.stroke_meta: dict = {}
        self.at = 0  # byte offset of the command being executed
        self.travel_ends = array("d")  # x0, y0, x1, y1 of each pen-up move (device units)
        self.travel_next = array("q")  # the stroke each one leads to
        self.deferred: list[int] | None = None
        """While ``run`` runs: the point count of each stroke it closed; their ``points`` stay
        None until :meth:`finish` converts ``deferred_points`` (device units) all at once."""
        self.deferred_points = array("d")

    def execute(self, command) -> None:
        """Execute one command of the language (a reader's own)."""
        raise NotImplementedError

    def run_tokens(self, tokenizer, text: str) -> Interpretation:
        """Run program ``text`` command by command as ``tokenizer`` (``feed``, ``close``) gives
        them, a chunk of bytes at a time (a chunk's commands are garbage once run)."""
        data = text.encode("latin-1")

        def commands():
            for start in range(0, len(data), _CHUNK):
                yield from tokenizer.feed(data[start:start + _CHUNK])
            yield from tokenizer.close()
        return self.run_commands(commands(), len(text))

    def run_commands(self, commands: Iterable, length: int) -> Interpretation:
        """Execute ``commands`` (each with an ``offset``) of a program ``length`` bytes long,
        pausing first at the known program's pause marks they reach (a language without a pause
        command has them only as offsets)."""
        self.deferred = []
        marks = list(self.known.pauses) if self.known else []
        for command in commands:
            self.at = command.offset
            while marks and marks[0].offset <= command.offset:
                self.pause(marks.pop(0))
            self.execute(command)
        self.at = length
        for mark in marks:
            self.pause(mark)
        return self.finish()

    def pause(self, mark: PauseMark) -> None:
        """The device stops here for the operator (with the pen up)."""
        self.lift()
        self.result.pauses.append(PauseEvent(mark.message, self.sheet_point(self.position),
                                             mark.offset, len(self.result.strokes)))

    def lower(self, offset: int, **meta) -> None:
        if self.stroke is None:
            self.stroke = [self.position]
            self.stroke_meta = dict(meta, offset=offset)

    def lift(self) -> None:
        if self.stroke is not None:
            if self.deferred is None:
                self.result.strokes.append(self.open_stroke())
            else:
                self.result.strokes.append(self._stroke(None))
                self.deferred.append(len(self.stroke))
                self.deferred_points.extend(chain.from_iterable(self.stroke))
            self.stroke = None

    def open_stroke(self) -> Stroke:
        """The stroke being drawn (pen down now), as it would be if the pen went up here."""
        return self._stroke(self.frame.to_sheet(self.stroke))

    def _stroke(self, points: np.ndarray | None) -> Stroke:
        meta = self.stroke_meta
        section = self.known.section_at(meta["offset"]) if self.known else None
        return Stroke(points=points, section=section, end=self.at, **meta)

    def move_to(self, target: tuple[float, float]) -> None:
        if self.stroke is not None:
            self.stroke.append(target)
        elif target != self.position:
            self.travel_ends.extend(self.position + target)
            self.travel_next.append(len(self.result.strokes))
        self.position = target

    def sheet_point(self, point: tuple[float, float]) -> tuple[float, float]:
        x, y = self.frame.to_sheet(point)[0].tolist()
        return x, y

    def finish(self) -> Interpretation:
        self.lift()
        if self.deferred is not None:
            self._convert_deferred()
        self.result.travels = self.sheet_travels()
        return self.result

    def _convert_deferred(self) -> None:
        """Give the strokes ``run`` closed their points in sheet mm (one conversion for all)."""
        import numpy as np

        sizes, raw = self.deferred, self.deferred_points
        self.deferred, self.deferred_points = None, array("d")
        sheet, start = self.frame.to_sheet(np.frombuffer(raw)), 0
        for stroke, size in zip(self.result.strokes[len(self.result.strokes) - len(sizes):], sizes):
            stroke.points = sheet[start:start + size]
            start += size

    def sheet_travels(self) -> list[Travel]:
        """The pen-up moves so far, in sheet mm."""
        import numpy as np

        flat = iter(self.frame.to_sheet(np.frombuffer(self.travel_ends)).ravel().tolist())
        return [Travel((x0, y0), (x1, y1), nxt)
                for (x0, y0, x1, y1), nxt in zip(zip(flat, flat, flat, flat), self.travel_next)]
