"""Read plotter programs back: what would the device draw, with which tool, where?

:func:`interpret` turns an HPGL or G-code program into an :class:`Interpretation`:
pen-down strokes in sheet millimetres with the tool state the program set, pen-up
travel moves (including the first one from the park position, where the last job
left the pen, and the last one back to it), and pauses.  Given a :class:`~foldfab.programs.program.Program` rather
than bare text, strokes are also labelled with their plan step, layer and
repetition, and HPGL pauses (which exist only as offsets) are placed.

:class:`HPGLTokenizer` is an incremental HP-GL tokenizer: feed it bytes as they
arrive, get complete :class:`HPGLCommand` objects.  It knows HP-GL's syntax (two-letter
mnemonics, numbers separated by commas, spaces or signs, optional ``;`` terminators,
``LB`` labels ended by ETX, and ``ESC .`` device-control sequences), not the meaning
of commands, so a simulated plotter can reuse it.  The machines that give commands
their meaning (:class:`HPGLMachine`, :class:`GcodeMachine`) are public for the same
reason: ``foldfab.sim`` runs them command by command on a virtual clock.
"""

from __future__ import annotations

import math
import re
from array import array
from dataclasses import dataclass, field
from functools import lru_cache
from itertools import chain
from typing import TYPE_CHECKING, Iterator, NamedTuple

from foldfab.errors import FoldfabError

if TYPE_CHECKING:
    import numpy as np

    from foldfab.devices import DeviceProfile, Frame
    from foldfab.programs.program import PauseMark, Program, Section

ESC, ETX = 0x1B, 0x03
ESC_WITH_PARAMETERS = b"@HIMNT"  # ESC . x <parameters> :   (the others take none)
_CHUNK = 1 << 16  # bytes HPGLMachine.run tokenizes at a time
_PARAM_RUN = re.compile(rb"[0-9+\-.,\s]*")
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)")
_NUMBER_BYTES = re.compile(_NUMBER.pattern.encode())
# Parameters that read without error: numbers separated by commas, whitespace or the
# next one's sign, and nothing else (the rule of HPGLTokenizer._command's loop).  Atomic
# numbers and possessive repeats: a text that is not plain fails in linear time.
_PLAIN = r"[\s,]*+(?:(?>{0})(?:[\s,]++(?>{0})|(?=[+-])(?>{0}))*+)?+[\s,]*+".format(_NUMBER.pattern)
_PLAIN_PARAMS = re.compile(_PLAIN)
_IDLE_SKIP = rb"[^A-Za-z\x1b\x80-\xff]*+"  # bytes the tokenizer passes over between commands
# A whole command as the byte-by-byte reader sees it from state "idle": bytes it skips,
# a two-letter ASCII mnemonic other than LB, its complete parameter run (group 2 if just
# integers between commas, as foldfab writes them, else group 3, plain), and the end of
# that run: a ";" (consumed) or the first byte of whatever follows.
_PLAIN_COMMAND = re.compile(_IDLE_SKIP + rb"(?![Ll][Bb])([A-Za-z]{2})"
                            rb"(?:(-?\d++(?:,-?\d++)*+)|(" + _PLAIN.encode() + rb"))"
                            rb"(?:;|(?=[^0-9+\-.,\s]))")
_SKIP = re.compile(_IDLE_SKIP)
_NAMES: dict[bytes, str] = {}  # mnemonic bytes as read -> upper-case name


class HPGLCommand(NamedTuple):
    """One HP-GL instruction: ``name`` is "PU", "SP"..., "LB", or "ESC.B" for device control.

    A named tuple rather than a frozen dataclass: a program of 100,000 strokes is 200,000
    of them, and a tuple is made in half the time."""

    name: str
    params: tuple[float, ...]
    offset: int
    """Byte offset of the command's first byte in the stream."""
    text: str | None = None
    """The label of ``LB``."""
    error: str | None = None
    """Why the parameters could not be read, if they could not."""
    part: int = 0
    """0, or the index of this coordinate pair's piece when the tokenizer splits coordinates."""


COORDINATE_COMMANDS = ("PU", "PD", "PA", "PR")


class HPGLTokenizer:
    """Incremental HP-GL tokenizer: ``feed(bytes)`` returns the commands completed so far.

    With ``split_coordinates``, ``PU``/``PD``/``PA``/``PR`` come out one coordinate pair
    at a time, each as soon as its pair is complete (``PD1,2,3,4;`` gives ``PD 1,2``
    at offset 0 and ``PD 3,4`` with ``part`` 1 at the ``3``); HP-GL means the same, and a
    plotter executes a long polyline pair by pair instead of holding it whole.

    Complete commands whose parameters read without error take a fast path (one regular
    expression match each); labels, ``ESC`` sequences, errors and a command still open at
    the end of the data go byte by byte.  Both give the same commands, however the stream
    is cut into ``feed`` calls.
    """

    def __init__(self, split_coordinates: bool = False) -> None:
        self.offset = 0  # bytes consumed so far
        self._split = split_coordinates
        self._state = "idle"
        self._name = ""
        self._start = 0
        self._part = 0
        self._pending = bytearray()

    @property
    def committed(self) -> int:
        """Every byte before this offset belongs to a command already returned, or to none."""
        return self.offset if self._state == "idle" else self._start

    def feed(self, data: bytes) -> list[HPGLCommand]:
        """Consume ``data``; return every command it completes."""
        out: list[HPGLCommand] = []
        i, n = 0, len(data)
        while i < n:
            state = self._state
            if state == "idle":
                i = self._plain_commands(data, i, out)
                if i == n:
                    break
            elif state == "params":
                end = _PARAM_RUN.match(data, i).end()
                self._pending += data[i:end]
                i = end
                if self._split and self._name in COORDINATE_COMMANDS:
                    out += self._pairs(self.offset + i)
                if i == n:
                    break
                byte = data[i]
                out.append(self._finish())
                if byte == ord(";"):
                    i += 1
                continue  # a letter or ESC starts the next command in state "idle"
            if state == "label":
                end = data.find(bytes([ETX]), i)
                if end < 0:
                    self._pending += data[i:]
                    i = n
                    break
                self._pending += data[i:end]
                out.append(self._finish())
                i = end + 1
                continue
            byte = data[i]
            position = self.offset + i
            i += 1
            if state == "idle":
                if byte == ESC:
                    self._state, self._start = "esc", position
                elif chr(byte).isalpha():
                    self._state, self._start, self._name = "mnemonic", position, chr(byte).upper()
                    self._part = 0
            elif state == "mnemonic":
                if chr(byte).isalpha():
                    self._name += chr(byte).upper()
                    self._state = "label" if self._name == "LB" else "params"
                else:  # a lone letter: report it, then read this byte afresh
                    out.append(HPGLCommand(self._name, (), self._start, error="not a mnemonic"))
                    self._state = "idle"
                    i -= 1
            elif state == "esc":
                self._state = "escdot" if byte == ord(".") else "idle"
            elif state == "escdot":
                self._name = "ESC." + chr(byte)
                if byte in ESC_WITH_PARAMETERS:
                    self._state = "escparams"
                else:
                    out.append(HPGLCommand(self._name, (), self._start))
                    self._state = "idle"
            elif state == "escparams":
                if byte == ord(":"):
                    out.append(self._finish(separator=";"))
                else:
                    self._pending.append(byte)
        self.offset += n
        return out

    def _plain_commands(self, data: bytes, i: int, out: list[HPGLCommand]) -> int:
        """Fast path in state "idle": append the commands of ``data[i:]`` that
        ``_PLAIN_COMMAND`` reads, up to the first it cannot, and pass over the bytes state
        "idle" ignores after them; return where the byte-by-byte reader takes over.

        The byte-by-byte reader would give the same commands (labels, ``ESC`` sequences,
        parameters with an error and a command not ended yet in ``data`` are left to it).
        """
        match, offset = _PLAIN_COMMAND.match, self.offset
        split, names = self._split, _NAMES
        while (found := match(data, i)) is not None:
            i = found.end()
            mnemonic, integers, plain = found.groups()
            name = names.get(mnemonic) or names.setdefault(mnemonic, mnemonic.upper().decode())
            group, params = (2, integers) if integers is not None else (3, plain)
            if split and name in COORDINATE_COMMANDS:
                self._name, self._start, self._part = name, offset + found.start(1), 0
                self._pending += params
                out += self._pairs(offset + found.end(group))
                out.append(self._finish())
            else:
                self._part = 0  # as any mnemonic leaves it (an ESC. instruction reads it)
                numbers = params.split(b",") if group == 2 else _NUMBER_BYTES.findall(params)
                out.append(HPGLCommand(name, tuple(map(float, numbers)), offset + found.start(1)))
        return _SKIP.match(data, i).end()

    def abort(self) -> None:
        """Drop the instruction being read (``ESC.K``: its bytes never form a command)."""
        self._pending.clear()
        self._state = "idle"

    def close(self) -> list[HPGLCommand]:
        """End of stream: return the command still waiting for a terminator, if any."""
        return [self._finish()] if self._state in ("params", "label") else []

    def _finish(self, separator: str = ",") -> HPGLCommand:
        text = self._pending.decode("latin-1")
        self._pending.clear()
        state, self._state = self._state, "idle"
        if state == "label":
            return HPGLCommand(self._name, (), self._start, text=text)
        return self._command(text, separator)

    def _pairs(self, position: int) -> list[HPGLCommand]:
        """Split complete coordinate pairs off the pending parameters (``position``: their end)."""
        text = self._pending.decode("latin-1")
        ends = [m.end() for m in _NUMBER.finditer(text) if m.end() < len(text)]  # followed by more
        if len(ends) < 2:
            return []
        pieces, cut = [], 0
        for end in ends[1::2]:
            pieces.append(self._command(text[cut:end], ","))
            self._start, cut = position - len(text) + end, end
            self._part += 1
        del self._pending[:cut]
        return pieces

    def _command(self, text: str, separator: str) -> HPGLCommand:
        if separator == "," and _PLAIN_PARAMS.fullmatch(text):  # no error: skip the checks
            numbers = tuple(map(float, _NUMBER.findall(text)))
            return HPGLCommand(self._name, numbers, self._start, part=self._part)
        numbers, end, bad = [], 0, False
        for match in _NUMBER.finditer(text):
            gap = text[end:match.start()]
            # numbers are separated by a separator, whitespace or the next one's sign
            bad |= bool(gap.replace(separator, " ").strip()) or \
                (bool(numbers) and not gap and match.group()[0] not in "+-")
            numbers.append(float(match.group()))
            end = match.end()
        bad |= bool(text[end:].replace(separator, " ").strip())
        error = f"cannot read parameters {text!r}" if bad else None
        return HPGLCommand(self._name, tuple(numbers), self._start, error=error, part=self._part)


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


def interpret(program: Program | str, device: DeviceProfile,
              sheet: tuple[float, float] | None = None) -> Interpretation:
    """Interpret ``program`` (a Program or bare text) as ``device`` would run it.

    ``sheet`` (w, h mm) fixes the sheet-to-device mapping; default: the profile's sheet.
    """
    from foldfab.programs.program import Program

    frame = device.frame(sheet or device.sheet)
    text = program.text if isinstance(program, Program) else program
    known = program if isinstance(program, Program) else None
    if known is not None and known.protocol != device.protocol:
        raise FoldfabError(f"a {known.protocol} program cannot run on {device.name} "
                           f"({device.protocol})")
    machine = (HPGLMachine if device.protocol == "hpgl" else GcodeMachine)(device, frame, known)
    machine.position = device.park_units  # where the last job left the pen, as the optimizer assumes
    return machine.run(text)


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


class HPGLMachine(Machine):
    """HP-GL semantics for PU, PD, PA, PR, SP, VS, FS, IN, DF."""

    def __init__(self, device, frame, known):
        super().__init__("hpgl", device, frame, known)
        self.absolute = True
        self.pen = 0
        self.reset()

    def reset(self) -> None:
        self.speeds: dict[int | None, float] = {None: self.device.motion.draw_speed}
        self.forces: dict[int | None, float | None] = {None: None}

    def run(self, text: str) -> Interpretation:
        tokenizer = HPGLTokenizer()
        self.deferred = []
        marks = list(self.known.pauses) if self.known else []
        data = text.encode("latin-1")
        for start in range(0, len(data), _CHUNK):  # a chunk's commands are garbage once run
            self._run_commands(tokenizer.feed(data[start:start + _CHUNK]), marks)
        self._run_commands(tokenizer.close(), marks)
        self.at = len(text)
        for mark in marks:
            self.pause(mark)
        return self.finish()

    def _run_commands(self, commands: list[HPGLCommand], marks: list[PauseMark]) -> None:
        """Execute ``commands``, pausing first at the ``marks`` they reach (popped)."""
        for command in commands:
            self.at = command.offset
            while marks and marks[0].offset <= command.offset:
                self.pause(marks.pop(0))
            self.execute(command)

    def pause(self, mark: PauseMark) -> None:
        self.lift()
        self.result.pauses.append(PauseEvent(mark.message, self.sheet_point(self.position),
                                             mark.offset, len(self.result.strokes)))

    def execute(self, command: HPGLCommand) -> None:
        name, params = command.name, command.params
        if command.error:
            self.result.ignored.append(f"{name} at byte {command.offset}: {command.error}")
        elif name in COORDINATE_COMMANDS:
            if name == "PU":
                self.lift()
            elif name == "PD":
                if self.stroke is None:
                    self.lower(command.offset, pen=self.pen, force=self.current(self.forces),
                               speed=self.current(self.speeds), pen_down=None)
            else:
                self.absolute = name == "PA"
            if len(params) % 2:
                self.result.ignored.append(f"{name} at byte {command.offset}: odd coordinate count")
            if self.absolute:
                for i in range(1, len(params), 2):
                    self.move_to((params[i - 1], params[i]))
            else:
                for x, y in zip(params[::2], params[1::2]):
                    self.move_to((x + self.position[0], y + self.position[1]))
        elif name == "SP":
            self.lift()
            self.pen = int(params[0]) if params else 0
        elif name in ("VS", "FS"):
            table = self.speeds if name == "VS" else self.forces
            default = self.device.motion.draw_speed if name == "VS" else None
            value = default if not params else params[0] * 10 if name == "VS" else params[0]
            if len(params) > 1:  # "VS v,pen": for that pen only
                table[int(params[1])] = value
            else:  # for every pen (VS is in cm/s)
                table.clear()
                table[None] = value
        elif name in ("IN", "DF"):
            if name == "IN":
                self.lift()
            self.absolute = True
            self.reset()
        else:
            self.result.ignored.append(name)

    def current(self, table: dict):
        return table.get(self.pen, table[None])


_WORD = re.compile(r"([A-Z])\s*([-+]?(?:\d+\.?\d*|\.\d+))")
_COMMENT = re.compile(r"\(([^)]*)\)?|;(.*)$")
_WORDS_ONLY = re.compile(r"(?:\s*" + _WORD.pattern + r")*\s*")  # nothing _WORD leaves unread
_XY_LINE = re.compile(r"X([-+]?\d+\.?\d*) Y([-+]?\d+\.?\d*)(?: F(\d+\.?\d*))?")
"""Lines of X, Y and perhaps F (as _WORD reads them, nothing else): GcodeMachine takes their
words without :func:`read_gcode_line`."""
SUPPORTED_G = frozenset({0, 1, 4, 17, 20, 21, 90, 91, 92})
SUPPORTED_M = frozenset({0, 2, 3, 5})


class GcodeLine(NamedTuple):
    """One G-code line read but not yet executed (a named tuple: a program has many)."""

    raw: str
    offset: int
    code: str
    """The text outside comments, upper case."""
    words: tuple[tuple[str, float], ...]
    """(letter, value) in order."""
    comments: tuple[str, ...]
    unreadable: str
    """Text outside comments that is not a letter followed by a number ("" if none)."""
    unsupported: tuple[str, ...]
    """G and M words GRBL 1.1 does not take ("G2", "M8")."""

    @property
    def problems(self) -> list[str]:
        """What an interpreter reports as ignored."""
        lead = [f"line at byte {self.offset}: {self.raw.strip()!r}"] if self.unreadable else []
        return lead + list(self.unsupported)


def read_gcode_line(raw: str, offset: int = 0) -> GcodeLine:
    """Words, comments and problems of the line ``raw`` found at byte ``offset``."""
    return GcodeLine(raw, offset, *_read_code(raw))


@lru_cache(maxsize=64)  # a program repeats its pen-up and pen-down lines thousands of times
def _read_code(raw: str) -> tuple[str, tuple, tuple, str, tuple]:
    """Code, words, comments, unreadable text and unsupported words of the line ``raw``."""
    if "(" in raw or ";" in raw:
        comments = tuple(a or b for a, b in _COMMENT.findall(raw))
        code = _COMMENT.sub(" ", raw).upper()
    else:  # most lines: no comment to look for
        comments, code = (), raw.upper()
    words = tuple([(letter, float(number)) for letter, number in _WORD.findall(code)])
    unsupported = tuple(f"{letter}{value:g}" for letter, value in words
                        if (letter == "G" and value not in SUPPORTED_G)
                        or (letter == "M" and value not in SUPPORTED_M)) if "G" in code or "M" in code else ()
    unreadable = "" if _WORDS_ONLY.fullmatch(code) else _WORD.sub(" ", code).strip()
    return code, words, comments, unreadable, unsupported


class GcodeMachine(Machine):
    """GRBL semantics for G0 G1 G4 G17 G20 G21 G90 G91 G92 M0 M2 M3 M5 and X Y Z F S."""

    def __init__(self, device, frame, known):
        super().__init__("gcode", device, frame, known)
        gcode = device.gcode
        downs = [layer.pen_down for layer in device.layers.values()]
        self.servo = isinstance(gcode.pen_up, str)
        self.down_commands = {_servo_key(d) for d in downs if isinstance(d, str)}
        self.down_limit = None if self.servo else max(downs) + 1e-3  # z <= this: pen down
        self.messages = {m.offset: m.message for m in known.pauses} if known else {}
        self.motion, self.feed, self.spindle = "G0", None, 0.0
        self.z, self.absolute, self.scale = gcode.pen_up if not self.servo else 0.0, True, 1.0
        self.g92 = (0.0, 0.0)
        self.g92_pending = False
        self.is_down = False
        self.down_by: float | str | None = None
        self.comments: list[str] = []

    def run(self, text: str) -> Interpretation:
        offset = 0
        self.deferred = []
        execute, size = self.execute, len(text)
        for raw in text.split("\n"):
            end = offset + len(raw) + 1
            self.at = offset
            execute(raw, offset, min(end, size))
            offset = end
        self.at = size
        return self.finish()

    def execute(self, raw: str, offset: int, end: int) -> None:
        plain = _XY_LINE.fullmatch(raw)
        if plain is None:
            self.apply(read_gcode_line(raw, offset), end)
            return
        x, y, feed = plain.groups()  # most lines: their words without reading them one by one
        values = {"X": float(x), "Y": float(y)}
        if feed is not None:
            values["F"] = float(feed)
        self.take(values, offset, end)

    def apply(self, line: GcodeLine, end: int) -> None:
        """Execute a line read by :func:`read_gcode_line` (``end``: offset after its newline)."""
        offset = line.offset
        if line.unreadable or line.unsupported:
            self.result.ignored.extend(line.problems)
        if not line.words:
            self.comments.extend(c.strip() for c in line.comments)
            return
        if "G" in line.code or "M" in line.code:
            values = {}
            for letter, value in line.words:
                if letter == "G":
                    self.g_word(value)
                elif letter == "M":
                    values.setdefault("M", []).append(value)
                else:
                    values[letter] = value
        else:  # most lines: coordinates and a feed
            values = dict(line.words)
        self.take(values, offset, end)

    def take(self, values: dict, offset: int, end: int) -> None:
        """Execute a line's words but G (letter -> value, "M" -> the M values in order)."""
        if "F" in values:
            self.feed = values["F"] * self.scale / 60
        if "S" in values:
            self.spindle = values["S"]
        if self.g92_pending:
            self.set_position(values)
        elif "X" in values or "Y" in values:
            self.xy_move(values)
        if "Z" in values and not self.g92_pending:
            self.z = values["Z"] * self.scale + (0 if self.absolute else self.z)
            if not self.servo:
                self.pen_state(self.z <= self.down_limit, self.z, offset)
        self.g92_pending = False
        for m in values.get("M", []):
            self.m_word(m, offset, end)
        self.comments = []

    def g_word(self, value: float) -> None:
        if value in (0, 1):
            self.motion = f"G{int(value)}"
        elif value in (20, 21):
            self.scale = 25.4 if value == 20 else 1.0
        elif value in (90, 91):
            self.absolute = value == 90
        elif value == 92:
            self.g92_pending = True

    def set_position(self, values: dict) -> None:
        """G92: the current point gets the given coordinates (an offset, not a move)."""
        x = values.get("X", None)
        y = values.get("Y", None)
        gx, gy = self.g92
        if x is not None:
            gx = self.position[0] - x * self.scale
        if y is not None:
            gy = self.position[1] - y * self.scale
        self.g92 = (gx, gy)

    def xy_move(self, values: dict) -> None:
        x, y = self.position
        if self.absolute:
            x = values["X"] * self.scale + self.g92[0] if "X" in values else x
            y = values["Y"] * self.scale + self.g92[1] if "Y" in values else y
        else:
            x += values.get("X", 0.0) * self.scale
            y += values.get("Y", 0.0) * self.scale
        if self.stroke is not None and len(self.stroke) == 1:
            speed = self.feed if self.motion == "G1" and self.feed else \
                self.device.motion.travel_speed
            self.stroke_meta["speed"] = speed
        self.move_to((x, y))

    def m_word(self, value: float, offset: int, end: int) -> None:
        if value == 0:
            message = self.messages.get(end, " ".join(c for c in self.comments if c))
            self.result.pauses.append(PauseEvent(message, self.sheet_point(self.position), end,
                                                 len(self.result.strokes)))
        elif value == 2:
            self.pen_state(False, None, offset)
        elif value in (3, 5) and self.servo:
            command = "M5" if value == 5 else f"M3 S{self.spindle:g}"
            self.pen_state(_servo_key(command) in self.down_commands, command, offset)

    def pen_state(self, down: bool, by, offset: int) -> None:
        if down and not self.is_down:
            speed = self.feed or self.device.motion.draw_speed
            self.lower(offset, pen=None, force=None, speed=speed, pen_down=by)
        elif not down:
            self.lift()
        self.is_down = down


def pen_states(text: str, protocol: str, device: DeviceProfile) -> Iterator[tuple[int, Machine]]:
    """(end offset, machine) after each step a plotter takes in program ``text``: an HP-GL
    coordinate pair or instruction, a G-code line (at least one, even in an empty text).
    The machine is the same object, updated in place."""
    frame = device.frame(device.sheet)
    if protocol == "hpgl":
        machine = HPGLMachine(device, frame, None)
        tokenizer = HPGLTokenizer(split_coordinates=True)
        commands = tokenizer.feed(text.encode("ascii")) + tokenizer.close()
        for command, end in zip(commands, [c.offset for c in commands[1:]] + [len(text)]):
            machine.at = command.offset
            machine.execute(command)
            yield end, machine
        return
    machine = GcodeMachine(device, frame, None)
    offset = 0
    for raw in text.split("\n"):
        end = min(offset + len(raw) + 1, len(text))
        machine.execute(raw, offset, end)
        yield end, machine
        offset = end


def _servo_key(command: str) -> tuple[str, float | None]:
    """("M3", S value) or ("M5", None): servo commands compared by value, not spelling."""
    words = dict(_WORD.findall(command.upper()))
    return ("M5", None) if float(words["M"]) == 5 else ("M3", float(words.get("S", "nan")))
