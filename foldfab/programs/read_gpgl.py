"""Reading GP-GL: the tokenizer and the machine that gives its commands their meaning.

:class:`GPGLTokenizer` is incremental (feed it bytes as they arrive, get complete
:class:`GPGLCommand` objects), so the simulated cutter reuses it: a command is a mnemonic (the
characters before the first number: ``M``, ``D``, ``FX``, ``!``, ``\\``, ``TB``...) and numbers
separated by commas, ended by ``\\x03``; ``ESC`` and the byte after it are a device-control
instruction (``ESC04`` initialise, ``ESC05`` status), whatever surrounds them.
:class:`GPGLMachine` executes ``M`` (tool up, absolute), ``D`` (tool down, absolute; a ``D`` to
the point the tool stands on lowers it there), ``J`` (tool holder), ``FX`` (force), ``!``
(speed, cm/s), ``H`` and ``TT`` (home) and ``ESC04`` (initialise), and accepts the setup
commands :mod:`~foldfab.programs.gpgl` writes.
"""

from __future__ import annotations

import re
from typing import NamedTuple

from foldfab.programs.machine import Interpretation, Machine

ESC, ETX = 0x1B, 0x03
_END = re.compile(rb"[\x03\x1b]")
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)")
_PARAMS = re.compile(r"\s*(?:{0}\s*(?:,\s*{0}\s*)*)?".format(_NUMBER.pattern))
_MNEMONIC = re.compile(r"[A-Za-z!\\\[]*")  # letters, and the symbols GP-GL names commands with
ACCEPTED = frozenset(("FC", "FN", "TB", "\\", "Z", "FE", "FF", "FY", "FW", "TJ", "L", "ESC05", "ESC15"))
"""Setup commands and questions that move nothing: accepted, no effect on the drawing."""
TOOL_SETTINGS = {"J": None, "FX": 1, "!": 1, "FC": 2}
"""The tool state, with the index of the parameter naming a tool holder (None: J names it)."""


class GPGLCommand(NamedTuple):
    """One GP-GL command: ``name`` is its mnemonic, or ``ESCxx`` for a device-control pair."""

    name: str
    params: tuple[float, ...]
    offset: int
    """Byte offset of the command's first byte in the stream."""
    error: str | None = None
    """Why the command could not be read, if it could not."""


class GPGLTokenizer:
    """Incremental GP-GL tokenizer: ``feed(bytes)`` returns the commands completed so far."""

    def __init__(self) -> None:
        self.offset = 0  # bytes consumed so far
        self._pending = bytearray()
        self._start: int | None = None  # offset of the command being read
        self._escape: int | None = None  # offset of an ESC whose second byte has not come

    @property
    def committed(self) -> int:
        """Every byte before this offset belongs to a command already returned, or to none."""
        starts = [s for s in (self._start, self._escape) if s is not None]
        return min(starts) if starts else self.offset

    def feed(self, data: bytes) -> list[GPGLCommand]:
        """Consume ``data``; return every command it completes."""
        out: list[GPGLCommand] = []
        i, n = 0, len(data)
        while i < n:
            if self._escape is not None:
                out.append(GPGLCommand(f"ESC{data[i]:02x}", (), self._escape))
                self._escape = None
                i += 1
                continue
            found = _END.search(data, i)
            end = found.start() if found else n
            if end > i and self._start is None:
                self._start = self.offset + i
            self._pending += data[i:end]
            if found is None:
                break
            if data[end] == ESC:  # a device-control pair: the command being read goes on after it
                self._escape = self.offset + end
            elif self._start is not None:
                out.append(self._command(self._pending.decode("latin-1"), self._start))
                self._pending.clear()
                self._start = None
            i = end + 1
        self.offset += n
        return out

    def close(self) -> list[GPGLCommand]:
        """End of stream: nothing (a command without its ETX is never executed)."""
        return []

    def abort(self) -> None:
        """Drop the command being read (the cutter was initialised)."""
        self._pending.clear()
        self._start = None

    @staticmethod
    def _command(text: str, offset: int) -> GPGLCommand:
        name = _MNEMONIC.match(text).group()
        rest = text[len(name):]
        numbers = tuple(float(m) for m in _NUMBER.findall(rest))
        if not name.strip():
            return GPGLCommand(name, numbers, offset, error=f"no mnemonic in {text!r}")
        if not _PARAMS.fullmatch(rest):
            return GPGLCommand(name, numbers, offset, error=f"cannot read parameters {rest!r}")
        return GPGLCommand(name, numbers, offset)


def tokenize(text: str) -> list[GPGLCommand]:
    """Every command of a whole program ``text``."""
    return GPGLTokenizer().feed(text.encode("latin-1"))


def tool_state(text: str) -> str:
    """The commands that restore the tool state program ``text`` leaves: the last ``J``, and per
    tool holder the last ``FX``, ``!`` and ``FC`` (since the last initialisation)."""
    latest: dict[tuple, str] = {}
    for command in tokenize(text):
        if command.name == "ESC04":
            latest.clear()
        elif command.name in TOOL_SETTINGS:
            index = TOOL_SETTINGS[command.name]
            key = (command.name, command.params[index:index + 1] if index is not None else ())
            latest.pop(key, None)
            end = text.find("\x03", command.offset)
            latest[key] = text[command.offset:end + 1 if end >= 0 else len(text)]
    return "".join(latest.values())


class GPGLMachine(Machine):
    """GP-GL semantics for M, D, J, FX, !, H, TT and ESC04."""

    def __init__(self, device, frame, known):
        super().__init__("gpgl", device, frame, known)
        self.tool = 1
        self.reset()

    def reset(self) -> None:
        self.speeds: dict[int | None, float] = {None: self.device.motion.draw_speed}
        self.forces: dict[int | None, float | None] = {None: None}

    def run(self, text: str) -> Interpretation:
        return self.run_tokens(GPGLTokenizer(), text)

    def execute(self, command: GPGLCommand) -> None:
        name, params = command.name, command.params
        if command.error:
            self.result.ignored.append(f"{name} at byte {command.offset}: {command.error}")
        elif name in ("M", "D"):
            if not params or len(params) % 2:
                self.result.ignored.append(f"{name} at byte {command.offset}: odd coordinate count")
            if name == "M":
                self.lift()
            for target in zip(params[::2], params[1::2]):
                if name == "D" and self.stroke is None:
                    self.lower(command.offset, pen=self.tool, force=self.current(self.forces),
                               speed=self.current(self.speeds), pen_down=None)
                    if target == self.position:  # lowered where it stands
                        continue
                self.move_to(target)
        elif name == "J":
            self.lift()
            self.tool = int(params[0]) if params else 1
        elif name in ("FX", "!"):
            table = self.forces if name == "FX" else self.speeds
            value = params[0] * 10 if name == "!" and params else params[0] if params else \
                (None if name == "FX" else self.device.motion.draw_speed)
            if len(params) > 1:  # "FX f,t": for tool holder t only
                table[int(params[1])] = value
            else:
                table.clear()
                table[None] = value
        elif name in ("H", "TT"):
            self.lift()
            self.move_to((0.0, 0.0))
        elif name == "ESC04":
            self.lift()
            self.tool = 1
            self.reset()
        elif name not in ACCEPTED:
            self.result.ignored.append(name)

    def current(self, table: dict):
        return table.get(self.tool, table[None])
