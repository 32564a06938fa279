"""Reading G-code: GRBL's lines read (:func:`read_gcode_line`) and executed (:class:`GcodeMachine`).

:class:`GcodeMachine` is public so that ``foldfab.sim`` can run it line by line on a virtual
clock, and the GRBL sender can read the lines it streams with :func:`read_gcode_line`.
"""

from __future__ import annotations

import re
from functools import lru_cache
from typing import NamedTuple

from foldfab.programs.machine import Interpretation, Machine, PauseEvent

_WORD = re.compile(r"([A-Z])\s*([-+]?(?:\d+\.?\d*|\.\d+))")
_COMMENT = re.compile(r"\(([^)]*)\)?|;(.*)$")
_WORDS_ONLY = re.compile(r"(?:\s*" + _WORD.pattern + r")*\s*")  # nothing _WORD leaves unread
_XY_LINE = re.compile(r"X([-+]?\d+\.?\d*) Y([-+]?\d+\.?\d*)(?: F(\d+\.?\d*))?")
"""Lines of X, Y and perhaps F (as _WORD reads them, nothing else): GcodeMachine takes their
words without :func:`read_gcode_line`."""
SUPPORTED_G = frozenset({0, 1, 4, 17, 20, 21, 90, 91, 92})
SUPPORTED_M = frozenset({0, 2, 3, 4, 5})


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
    """GRBL semantics for G0 G1 G4 G17 G20 G21 G90 G91 G92 M0 M2 M3 M4 M5 and X Y Z F S.

    A laser (GRBL's laser mode, ``$32=1``) draws on ``G1`` moves while ``M3`` or ``M4`` is on
    with ``S`` above 0, and never on ``G0``; each stroke records its power (``S`` / ``$30``),
    and a change of power starts a new stroke."""

    def __init__(self, device, frame, known):
        super().__init__("gcode", device, frame, known)
        gcode = device.gcode
        downs = [layer.pen_down for layer in device.layers.values()]
        self.laser = device.laser
        self.servo = isinstance(gcode.pen_up, str)
        self.down_commands = {_servo_key(d) for d in downs if isinstance(d, str)}
        self.down_limit = None if self.servo or self.laser else max(downs) + 1e-3  # z <= this: pen down
        self.messages = {m.offset: m.message for m in known.pauses} if known else {}
        self.motion, self.feed, self.spindle = "G0", None, 0.0
        self.beam: str | None = None
        """The spindle (laser) state GRBL's M3/M4 set, None after M5 (and at the start)."""
        self.laser_mode = True
        """GRBL's ``$32``: a board without laser mode keeps the beam on during G0 moves too."""
        self.z, self.absolute, self.scale = gcode.pen_up if self.down_limit is not None else 0.0, True, 1.0
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
            if self.laser:
                self.beam_state(offset)
            self.xy_move(values)
        if "Z" in values and not self.g92_pending:
            self.z = values["Z"] * self.scale + (0 if self.absolute else self.z)
            if self.down_limit is not None:
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
            self.beam = None  # M2 resets the spindle to M5
        elif value in (3, 4, 5) and self.laser:
            self.beam = None if value == 5 else f"M{value:g}"
            if value == 5:
                self.lift()
        elif value in (3, 5) and self.servo:
            command = "M5" if value == 5 else f"M3 S{self.spindle:g}"
            self.pen_state(_servo_key(command) in self.down_commands, command, offset)

    def beam_state(self, offset: int) -> None:
        """A laser before a move: on for a G1 move with M3/M4 and S > 0, at this power."""
        full = self.device.gcode.spindle_max
        on = self.beam and self.spindle > 0 and (self.motion == "G1" or not self.laser_mode)
        power = min(self.spindle, full) / full if on else None
        if self.stroke is not None and self.stroke_meta["power"] != power:
            self.lift()
        if power is not None and self.stroke is None:
            self.lower(offset, pen=None, force=None, speed=self.feed or self.device.motion.draw_speed,
                       pen_down=None, power=power)

    def pen_state(self, down: bool, by, offset: int) -> None:
        if down and not self.is_down:
            speed = self.feed or self.device.motion.draw_speed
            self.lower(offset, pen=None, force=None, speed=speed, pen_down=by)
        elif not down:
            self.lift()
        self.is_down = down


def _servo_key(command: str) -> tuple[str, float | None]:
    """("M3", S value) or ("M5", None): servo commands compared by value, not spelling."""
    words = dict(_WORD.findall(command.upper()))
    return ("M5", None) if float(words["M"]) == 5 else ("M3", float(words.get("S", "nan")))
