"""What a program draws, as arrays: recorded by the writer as it writes, or taken from a read-back.

The report and the time estimate need the strokes (points, speed, layer), the pen-up moves and
the pauses a program makes the device draw.  Reading the program back
(:func:`~foldfab.programs.interpret.interpret`) finds them one command at a time; the writers of
HP-GL and G-code know them already, since they emit exactly those points, rounded as the text
rounds them: they record them in a :class:`Recorder`, one array per sweep, and
:meth:`Recording.drawn` gives the same :class:`Drawn` arrays a read-back gives
(:func:`~foldfab.programs.machine.from_interpretation`).  :func:`verify` compares the two: the
read-back stays the oracle (``foldfab export --verify``, and ``foldfab plot`` before it sends).
"""

from __future__ import annotations

from array import array
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from foldfab.errors import FoldfabError

if TYPE_CHECKING:
    import numpy as np

    from foldfab.devices import Frame

TOLERANCE_MM = 1e-6
"""How far a point recorded by the writer may be from the one read back (float rounding of the
decimal text, never a plotter unit)."""


@dataclass(frozen=True, eq=False)
class Drawn:
    """Strokes, pen-up moves and pauses of a program, in sheet mm, as arrays."""

    points: np.ndarray
    """(N, 2): every stroke's points, one stroke after another."""
    starts: np.ndarray
    """(S,): the row of ``points`` where each stroke starts."""
    speeds: np.ndarray
    """(S,): mm/s as the device executes each stroke."""
    layers: np.ndarray
    """(S,): each stroke's layer, an index into ``names``."""
    names: tuple[str, ...]
    """The layer names in order of first appearance."""
    travels: np.ndarray
    """(T, 4): x0, y0, x1, y1 of each pen-up move."""
    leads_to: np.ndarray
    """(T,): the stroke each move leads to (the stroke count for the last ones)."""
    pauses: tuple[str, ...]
    """The operator's messages, in order."""
    byte_ends: np.ndarray | None = None
    """(S,): where in the program text each stroke's bytes end (the offset of the command that
    lifts the pen), for the serial line's time; None where unknown."""


@dataclass
class Recording:
    """What a writer drew, in device units as its text gives them (see :class:`Recorder`)."""

    chunks: list = field(default_factory=list)
    """One (M, 2) float array per sweep: its strokes' points, one stroke after another."""
    sizes: array = field(default_factory=lambda: array("q"))
    speeds: array = field(default_factory=lambda: array("d"))
    layers: array = field(default_factory=lambda: array("q"))
    names: dict[str, int] = field(default_factory=dict)
    travels: array = field(default_factory=lambda: array("d"))
    leads_to: array = field(default_factory=lambda: array("q"))
    byte_ends: array = field(default_factory=lambda: array("q"))
    """Per stroke, the program offset where its bytes end (the writer appends it, :meth:`Recorder.ended`)."""

    def drawn(self, frame: Frame, pauses: tuple[str, ...]) -> Drawn:
        """The recording in sheet mm (through ``frame``, as a read-back converts)."""
        import numpy as np

        sizes = np.frombuffer(self.sizes, dtype=np.int64).astype(np.intp)
        if len(self.chunks) > 1:   # kept as one array: the sweeps' and their join are not held at once
            self.chunks[:] = [np.concatenate(self.chunks)]
        points = frame.to_sheet(self.chunks[0]) if self.chunks else np.zeros((0, 2))
        travels = frame.to_sheet(np.frombuffer(self.travels)).reshape(-1, 4)
        return Drawn(points, np.cumsum(sizes) - sizes, np.frombuffer(self.speeds).copy(),
                     np.frombuffer(self.layers, dtype=np.int64).astype(np.intp), tuple(self.names), travels,
                     np.frombuffer(self.leads_to, dtype=np.int64).astype(np.intp), pauses,
                     np.frombuffer(self.byte_ends, dtype=np.int64).astype(np.intp)
                     if len(self.byte_ends) == len(sizes) else None)


class Recorder:
    """Follows the pen as a writer moves it: pen-up moves (only where the pen is not already,
    as a device goes nowhere then) and strokes, each a sweep's worth at a time."""

    def __init__(self, start: tuple[float, float]):
        self.position = (float(start[0]), float(start[1]))
        self.record = Recording()

    def move(self, target: tuple[float, float]) -> None:
        """A pen-up move to ``target`` (device units)."""
        target = (float(target[0]), float(target[1]))
        if target != self.position:
            self.record.travels.extend(self.position + target)
            self.record.leads_to.append(len(self.record.sizes))
        self.position = target

    def strokes(self, points: np.ndarray, sizes: np.ndarray, speed: float, layer: str) -> None:
        """Strokes of ``sizes`` points each (at least one), stored one after another in
        ``points`` (M, 2; device units as the text gives them), each reached by a pen-up
        move from where the pen is, drawn at ``speed`` mm/s on ``layer``."""
        import numpy as np

        if not len(sizes):
            return
        record = self.record
        points = np.asarray(points, dtype=float).reshape(-1, 2)
        ends = np.cumsum(sizes)
        firsts, lasts = points[ends - np.asarray(sizes)], points[ends - 1]
        before = np.vstack([np.asarray(self.position)[None, :], lasts[:-1]])
        moved = np.flatnonzero(np.any(before != firsts, axis=1))
        # as bytes: extending an array by a numpy array goes element by element
        record.travels.frombytes(np.hstack([before[moved], firsts[moved]]).tobytes())
        record.leads_to.frombytes((moved + len(record.sizes)).astype(np.int64).tobytes())
        record.chunks.append(points)
        record.sizes.frombytes(np.asarray(sizes, dtype=np.int64).tobytes())
        record.speeds.frombytes(np.full(len(sizes), float(speed)).tobytes())
        record.layers.frombytes(np.full(len(sizes), record.names.setdefault(layer, len(record.names)),
                                        dtype=np.int64).tobytes())
        x, y = lasts[-1].tolist()
        self.position = (x, y)

    def ended(self, offset: int) -> None:
        """The next recorded stroke's bytes end at program ``offset`` (the writer says so as it writes)."""
        self.record.byte_ends.append(offset)

    def ends(self, offsets: np.ndarray) -> None:
        """:meth:`ended` for the next ``len(offsets)`` strokes at once."""
        import numpy as np

        self.record.byte_ends.frombytes(np.asarray(offsets, dtype=np.int64).tobytes())


def verify(recorded: Drawn, read: Drawn, what: str) -> None:
    """Refuse a program whose read-back (``read``) does not draw what its writer recorded."""
    import numpy as np

    def differ(message: str) -> FoldfabError:
        return FoldfabError(f"{what}: the program read back {message}; the program text is not what was "
                            "planned (a bug, or the text was changed): do not send it")

    if len(read.starts) != len(recorded.starts) or not np.array_equal(read.starts, recorded.starts):
        raise differ(f"draws {len(read.starts)} strokes of {len(read.points)} points, "
                     f"planned {len(recorded.starts)} of {len(recorded.points)}")
    far = np.flatnonzero(np.abs(read.points - recorded.points).max(axis=1, initial=0.0) > TOLERANCE_MM)
    if len(far):
        stroke = int(np.searchsorted(recorded.starts, far[0], side="right"))
        raise differ(f"moves stroke {stroke} to {tuple(np.round(read.points[far[0]], 3).tolist())} mm, "
                     f"planned {tuple(np.round(recorded.points[far[0]], 3).tolist())} mm")
    lines = np.flatnonzero(np.diff(recorded.starts, append=len(recorded.points)) > 1)  # a dot has no speed
    slower = lines[~np.isclose(read.speeds[lines], recorded.speeds[lines], rtol=1e-9, atol=0.0)]
    if len(slower):
        raise differ(f"draws stroke {slower[0] + 1} at {read.speeds[slower[0]]:g} mm/s, "
                     f"planned {recorded.speeds[slower[0]]:g}")
    if not np.array_equal(np.asarray(read.names, dtype=object)[read.layers],
                          np.asarray(recorded.names, dtype=object)[recorded.layers]):
        raise differ("puts strokes on other layers than planned")
    if (read.travels.shape != recorded.travels.shape or not np.array_equal(read.leads_to, recorded.leads_to)
            or not np.allclose(read.travels, recorded.travels, rtol=0.0, atol=TOLERANCE_MM)):
        raise differ(f"makes {len(read.travels)} pen-up moves, planned {len(recorded.travels)} elsewhere")
    if read.pauses != recorded.pauses:
        raise differ(f"pauses {len(read.pauses)} times, planned {len(recorded.pauses)}")
