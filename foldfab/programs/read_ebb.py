"""Reading EBB programs: the EiBotBoard commands foldfab (or anyone) sends an AxiDraw.

:func:`ebb_commands` splits a text into commands (``\\r`` ends each; a ``\\n`` after it is
ignored, as the firmware does); :class:`EbbMachine` gives them their meaning: ``SP`` raises and
lowers the pen, ``TP`` toggles it, ``SM`` and ``XM`` move the motors, ``HM`` moves them home (motor 1 turns by x + y,
motor 2 by x - y, so the head is at ((m1 + m2) / 2, (m1 - m2) / 2) in steps), ``EM``, ``SC``
and the queries draw nothing.  A drawn polyline's vertices are where the program rests with the
pen down (``SM,<ms>,0,0``, :data:`~foldfab.programs.ebb.VERTEX_MARK`); a program without such
marks keeps every move's end as a vertex.  The pen-up moves between two pen downs are one
travel.  A simulated EBB board runs the same machine command by command.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Iterator, NamedTuple

from foldfab.programs.machine import Interpretation, Machine

if TYPE_CHECKING:
    from foldfab.programs.program import PauseMark

QUIET = frozenset({"EM", "SC", "QM", "QP", "QG", "QS", "QB", "QE", "V", "CS", "R", "SR", "ES", "SL", "QL"})
"""Commands that configure or ask and draw nothing."""
MAX_FIELDS = 8


class EbbCommand(NamedTuple):
    """One command: its name (upper case), integer arguments, and where it starts."""

    name: str
    args: tuple[int, ...]
    offset: int
    error: str | None = None


def ebb_commands(text: str) -> Iterator[tuple[EbbCommand, int]]:
    """(command, end offset) for each ``\\r``-ended command of ``text`` (a last one without
    ``\\r`` too); blank commands are skipped."""
    offset, size = 0, len(text)
    while offset < size:
        end = text.find("\r", offset)
        end = size if end < 0 else end + 1
        raw = text[offset:end].strip()
        if raw:
            yield parse_command(raw, offset), end
        offset = end


def parse_command(raw: str, offset: int = 0) -> EbbCommand:
    """One command's text (without its ``\\r``) as an :class:`EbbCommand`."""
    fields = raw.split(",", MAX_FIELDS)
    name = fields[0].strip().upper()
    try:  # the firmware's arguments are 32-bit integers
        args = tuple(int(field) for field in fields[1:MAX_FIELDS] if len(field.strip()) <= 11)
    except ValueError:
        args = ()
    if len(args) != len(fields[1:MAX_FIELDS]) or any(abs(a) >= 2**31 for a in args):
        return EbbCommand(name, (), offset, f"cannot read arguments {raw[:40]!r}")
    return EbbCommand(name, args, offset)


class EbbMachine(Machine):
    """EiBotBoard semantics for SP, TP, SM, XM (and the commands that draw nothing)."""

    def __init__(self, device, frame, known):
        super().__init__("ebb", device, frame, known)
        x, y = device.park_units
        self.motors = [int(x + y), int(x - y)]
        self.home = tuple(self.motors)  # where EM counted from: HM goes back there
        self.position = (float(x), float(y))
        self.travel_from = self.position
        self.unmarked: list[tuple[float, float]] = []  # pen-down move ends since the last mark

    def run(self, text: str) -> Interpretation:
        return self.run_commands((command for command, _ in ebb_commands(text)), len(text))

    def pause(self, mark: PauseMark) -> None:
        super().pause(mark)
        self.flush_travel()  # the head rests at a pause: the moves before and after are two

    def execute(self, command: EbbCommand) -> None:
        name, args = command.name, command.args
        if command.error:
            self.result.ignored.append(f"{name} at byte {command.offset}: {command.error}")
        elif name == "SP" and args and args[0] in (0, 1):
            self.lift() if args[0] == 1 else self.lower_pen(command.offset)
        elif name == "TP":
            self.lift() if self.stroke is not None else self.lower_pen(command.offset)
        elif name in ("SM", "XM") and len(args) >= 2 and args[0] > 0:
            s1, s2 = args[1], args[2] if len(args) > 2 else 0
            if name == "XM":
                s1, s2 = s1 + s2, s1 - s2
            self.step(s1, s2)
        elif name == "HM" and args and args[0] > 0:
            target = args[1:3] if len(args) >= 3 else self.home
            self.step(target[0] - self.motors[0], target[1] - self.motors[1])
        elif name not in QUIET:
            self.result.ignored.append(f"{name} at byte {command.offset}")

    def lower_pen(self, offset: int) -> None:
        if self.stroke is None:
            self.flush_travel()
            section = self.known.section_at(offset) if self.known else None
            speed = section.tool.speed if section else self.device.motion.draw_speed
            self.lower(offset, pen=None, force=None, speed=speed, pen_down=None)

    def step(self, s1: int, s2: int) -> None:
        """Turn the motors by ``s1`` and ``s2`` steps (both zero: rest, a vertex when drawing)."""
        self.motors[0] += s1
        self.motors[1] += s2
        m1, m2 = self.motors
        self.position = ((m1 + m2) / 2, (m1 - m2) / 2)
        if self.stroke is None:
            return
        if s1 or s2:
            self.unmarked.append(self.position)
        else:
            self.stroke.append(self.position)
            self.unmarked.clear()

    def lift(self) -> None:
        if self.stroke is not None:
            self.stroke.extend(self.unmarked)
            self.unmarked.clear()
            self.travel_from = self.position
        super().lift()

    def flush_travel(self) -> None:
        """Record the pen-up moves since the pen went up as one travel."""
        if self.position != self.travel_from:
            self.travel_ends.extend(self.travel_from + self.position)
            self.travel_next.append(len(self.result.strokes))
        self.travel_from = self.position

    def finish(self) -> Interpretation:
        self.lift()
        self.flush_travel()
        return super().finish()
