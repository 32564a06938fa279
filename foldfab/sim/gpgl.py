"""A simulated GP-GL cutter (Silhouette Cameo and Portrait, Graphtec in GP-GL mode).

Parsing and drawing are foldfab's reader (:class:`~foldfab.programs.read_gpgl.GPGLTokenizer`,
:class:`~foldfab.programs.read_gpgl.GPGLMachine` with timing).  The cutter reads one command out
of its buffer when the previous move has ended, so its buffer drains at motion speed.  It has
no handshake: a host that sends more than the buffer holds loses bytes (the profile's
``[buffer] size``); the open drivers send a chunk, then poll the status until the cutter is
ready, and so does foldfab.

Device-control pairs are handled on arrival, never buffered: ``ESC 0x05`` answers the status
as the firmware does, one digit and ``\\x03`` (``0`` ready: nothing buffered and the carriage at
rest, ``1`` moving, ``2`` tray empty: no sheet loaded, see the ``unload_at`` option);
``ESC 0x04`` initialises (discards what the buffer holds, lifts the tool, forgets the tool
settings; the move in progress ends).  A command the reader does not know is skipped and
recorded in the statistics' errors.
"""

from __future__ import annotations

import re
from collections import deque
from typing import TYPE_CHECKING

from foldfab.programs.machine import Interpretation
from foldfab.programs.read_gpgl import GPGLCommand, GPGLTokenizer
from foldfab.sim.device import CommandDevice
from foldfab.sim.motion import TimedGPGL

if TYPE_CHECKING:
    from foldfab.devices import DeviceProfile
    from foldfab.sim.options import SimOptions

READY, MOVING, TRAY_EMPTY = "0", "1", "2"
"""The answers to ``ESC 0x05``."""


class GPGLCutter(CommandDevice):
    """Simulated GP-GL cutter."""

    protocol = "gpgl"
    TERMINATOR = "\x03"
    SPECIAL = re.compile(rb"\x1b")
    COMPLETES = re.compile(rb"\x03")

    def __init__(self, device: DeviceProfile, options: SimOptions):
        super().__init__(device, options)
        self.tokenizer = GPGLTokenizer()
        self.commands: deque[GPGLCommand] = deque()
        self.machine = TimedGPGL(device, self.frame, None)
        self.machine.start_timing(self._enqueue)
        self.count = 0  # commands received
        self.escape = False  # an ESC arrived; its second byte has not
        self.unload_at = options.unload_at
        self.unloaded = False
        if self.unload_at == 0:
            self._unload()

    def interpretation(self) -> Interpretation:
        return Interpretation("gpgl", strokes=self.strokes, travels=self.machine.sheet_travels())

    def _store(self, data: bytes) -> None:
        super()._store(data)
        if self.unload_at is not None and self.stats.bytes_received >= self.unload_at:
            self._unload()

    def _unload(self) -> None:
        """The sheet comes out (or was never loaded): the tool goes up and the cutter stops."""
        self.unloaded, self.unload_at = True, None
        self.machine.lift()
        self._freeze("unloaded")
        self.stats.errors.append("tray empty")

    def _execute(self, command: GPGLCommand) -> None:
        self.count += 1
        self.stats.commands += 1
        if self.count == self.options.error_at:
            self.stats.errors.append(f"command {self.count} skipped")
            return
        self.stats.last_activity = self.t
        machine = self.machine
        machine.at = command.offset
        ignored = len(machine.result.ignored)
        machine.execute(command)
        if len(machine.result.ignored) > ignored:
            self.stats.errors.append(f"command {self.count} not understood: {machine.result.ignored[-1]}")

    def status(self) -> str:
        """The answer to ``ESC 0x05``."""
        if self.unloaded:
            return TRAY_EMPTY
        busy = self.rx or self.commands or self.planner or self.block_end is not None
        return MOVING if busy else READY

    def _in_special(self) -> bool:
        return self.escape

    def _special(self, byte: int) -> None:
        if not self.escape:  # the ESC itself
            self.escape = True
            return
        self.escape = False
        self._when_running(lambda: self._device_control(byte))

    def _device_control(self, byte: int) -> None:
        if byte == 0x05:
            self.reply(self.status())
        elif byte == 0x04:
            self.tokenizer.abort()
            self.commands.clear()
            self._free(self.tokenizer.offset)
            self.machine.execute(GPGLCommand("ESC04", (), self.tokenizer.offset))

    def _idle_kind(self) -> str:
        machine = self.machine
        parked = machine.stroke is None and machine.result.strokes and machine.position == self.device.park_units
        return "parked" if parked else "starved"
