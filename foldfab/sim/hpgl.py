"""A simulated HP-GL plotter or cutter (HP 7475A, Graphtec, Roland in HP-GL mode).

Parsing and drawing are foldfab's interpreter (:class:`~foldfab.programs.read_hpgl.HPGLTokenizer`
splitting coordinate pairs, :class:`~foldfab.programs.read_hpgl.HPGLMachine` with timing).  The
plotter reads one instruction or coordinate pair out of its buffer when the previous
move has ended, so its buffer drains at motion speed.

Handshakes, chosen by the profile's ``[buffer] flow_control`` (or ``flow=``):
``xonxoff`` sends XOFF when the buffer fill reaches ``size - max(16, size/8)`` and XON
when it has drained to half; ``rtscts`` drives CTS with the same thresholds; ``ESC.B``
(free bytes) is always answered.  Device-control instructions (``ESC.``) are handled
on arrival and never buffered, as on HP plotters.

Answers (each ends in CR): ``ESC.B`` free bytes, ``ESC.L`` buffer size, ``ESC.E`` the
I/O error (0; 16 after bytes were lost to an overrun; 11 for an unknown ``ESC.``
instruction), ``ESC.K`` discards the instruction being read and the buffer (abort graphics;
the move in progress ends), ``ESC.O`` extended status (8 while the buffer is empty and the pen at
rest, else 0), ``ESC.A`` the profile's model; ``OI`` the same, ``OS`` status bits (1 pen down, 8
initialized, cleared by reading, 16 ready, 32 error), ``OE`` the HP-GL error (0 none,
1 instruction not recognized, 2 wrong parameters; cleared by reading), ``OA`` the pen
position ``x,y,pen`` in plotter units.  Output instructions execute in order, after
the moves before them.  Instructions the interpreter does not execute set ``OE`` 1.
"""

from __future__ import annotations

import re
from collections import deque

from typing import TYPE_CHECKING

from foldfab.programs.machine import Interpretation
from foldfab.programs.read_hpgl import COORDINATE_COMMANDS, HPGLCommand, HPGLTokenizer
from foldfab.sim.device import CommandDevice
from foldfab.sim.motion import TimedHPGL

if TYPE_CHECKING:
    from foldfab.devices import DeviceProfile
    from foldfab.sim.options import SimOptions

ACCEPTED_DEVICE_CONTROL = frozenset("ESC." + c for c in "@HIMNTRJ()YZ")
"""Handshake and configuration instructions: accepted, no effect in the simulator."""


class HPGLPlotter(CommandDevice):
    """Simulated HP-GL device."""

    protocol = "hpgl"
    TERMINATOR = "\r"
    SPECIAL = re.compile(rb"\x1b")
    COMPLETES = re.compile(rb"[;,\s+\-A-Za-z\x03]")

    def __init__(self, device: DeviceProfile, options: SimOptions):
        super().__init__(device, options)
        self.tokenizer = HPGLTokenizer(split_coordinates=True)
        self.escapes = HPGLTokenizer()
        self.commands: deque[HPGLCommand] = deque()
        self.machine = TimedHPGL(device, self.frame, None)
        self.machine.start_timing(self._enqueue)
        self.count = 0  # instructions received
        self.skipping = False  # the instruction being read is the injected error
        self.error = 0  # OE
        self.io_error = 0  # ESC.E
        self.initialized = True

    def interpretation(self) -> Interpretation:
        return Interpretation("hpgl", strokes=self.strokes, travels=self.machine.sheet_travels())

    def _execute(self, command: HPGLCommand) -> None:
        if command.part == 0:
            self.count += 1
            self.stats.commands += 1
            self.skipping = self.count == self.options.error_at
            if self.skipping:
                self._fail(self.options.error_code or 1)
        if self.skipping:
            return
        self.stats.last_activity = self.t
        answer = self._output(command.name)
        if answer is not None:
            self.reply(answer)
            return
        if command.name == "IN":
            self.error, self.initialized = 0, True
        machine = self.machine
        machine.at = command.offset
        ignored = len(machine.result.ignored)
        machine.execute(command)
        if len(machine.result.ignored) > ignored:
            odd = command.name in COORDINATE_COMMANDS and len(command.params) % 2
            self._fail(2 if command.error or odd else 1)

    def _output(self, name: str) -> str | None:
        """The answer to an output instruction (None: not one)."""
        machine = self.machine
        down = machine.stroke is not None
        if name == "OI":
            return self.device.model
        if name == "OS":
            status = down | 8 * self.initialized | 16 | 32 * bool(self.error)
            self.initialized = False
            return str(status)
        if name == "OE":
            error, self.error = self.error, 0
            return str(error)
        if name == "OA":
            x, y = machine.position
            return f"{round(x)},{round(y)},{int(down)}"
        return None

    def _fail(self, code: int) -> None:
        self.error = code
        self.stats.errors.append(f"OE {code}")

    def _in_special(self) -> bool:
        return self.escapes.committed != self.escapes.offset

    def _special(self, byte: int) -> None:
        for command in self.escapes.feed(bytes([byte])):
            self._when_running(lambda name=command.name: self._device_control(name))

    def _device_control(self, name: str) -> None:
        if name == "ESC.B":
            self.reply(str(self.free))
        elif name == "ESC.L":
            self.reply(str(self.size))
        elif name == "ESC.A":
            self.reply(self.device.model)
        elif name == "ESC.E":
            self.reply(str(self.io_error))
            self.io_error = 0
        elif name == "ESC.K":
            self.tokenizer.abort()
            self.commands.clear()
            self.skipping = False
            self._free(self.tokenizer.offset)
        elif name == "ESC.O":
            self.reply("8" if not self.rx and not self.planner else "0")
        elif name not in ACCEPTED_DEVICE_CONTROL:
            self.io_error = 11
            self.stats.errors.append("ESC.E 11")

    def _overrun(self) -> None:
        self.io_error = 16
        self.stats.errors.append("ESC.E 16")

    def _idle_kind(self) -> str:
        parked = self.machine.pen == 0 and self.machine.result.strokes
        return "parked (SP0)" if parked else "starved"
