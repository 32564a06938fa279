"""Reading HP-GL: the tokenizer and the machine that gives its commands their meaning.

:class:`HPGLTokenizer` is an incremental HP-GL tokenizer: feed it bytes as they
arrive, get complete :class:`HPGLCommand` objects.  It knows HP-GL's syntax (two-letter
mnemonics, numbers separated by commas, spaces or signs, optional ``;`` terminators,
``LB`` labels ended by ETX, and ``ESC .`` device-control sequences), not the meaning
of commands, so a simulated plotter can reuse it.  The machine that gives commands
their meaning (:class:`HPGLMachine`) is public for the same reason: ``foldfab.sim`` runs it
command by command on a virtual clock.
"""

from __future__ import annotations

import re
from typing import NamedTuple

from foldfab.programs.machine import Interpretation, Machine

ESC, ETX = 0x1B, 0x03
ESC_WITH_PARAMETERS = b"@HIMNT"  # ESC . x <parameters> :   (the others take none)
_PARAM_RUN = re.compile(rb"[0-9+\-.,\s]*")
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)")
_NUMBER_BYTES = re.compile(_NUMBER.pattern.encode())
# Parameters that read without error: numbers separated by commas, whitespace or the
# next one's sign, and nothing else (the rule of HPGLTokenizer._command's loop).  Atomic
# groups around every repeat (never backtracked into): a text that is not plain fails in
# linear time.  Written as (?>X*), not as the possessive X*+ it equals: before Python 3.11.5
# (Debian 12 has 3.11.2) possessive repeats could leave a capture group wrong (CPython
# gh-106052), and ``IN1,IN`` read group 2 as "1,".
_PLAIN = r"(?>[\s,]*)(?>(?:(?>{0})(?>(?:(?>[\s,]+)(?>{0})|(?=[+-])(?>{0}))*))?)(?>[\s,]*)".format(_NUMBER.pattern)
_PLAIN_PARAMS = re.compile(_PLAIN)
_IDLE_SKIP = rb"(?>[^A-Za-z\x1b\x80-\xff]*)"  # bytes the tokenizer passes over between commands
# A whole command as the byte-by-byte reader sees it from state "idle": bytes it skips,
# a two-letter ASCII mnemonic other than LB, its complete parameter run (group 2 if just
# integers between commas, as foldfab writes them, else group 3, plain), and the end of
# that run: a ";" (consumed) or the first byte of whatever follows.
_PLAIN_COMMAND = re.compile(_IDLE_SKIP + rb"(?![Ll][Bb])([A-Za-z]{2})"
                            rb"(?:((?>-?\d+(?:,-?\d+)*))|(" + _PLAIN.encode() + rb"))"
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
        return self.run_tokens(HPGLTokenizer(), text)

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
