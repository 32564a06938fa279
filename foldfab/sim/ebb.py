"""A simulated EiBotBoard (EBB), the controller of AxiDraw pen plotters.

Commands end with ``\\r`` (a ``\\n`` is skipped); replies end with ``\\r\\n``, as the firmware
sends them and plotink's ``ebb_serial`` reads them.  Drawing is foldfab's reader
(:class:`~foldfab.programs.read_ebb.EbbMachine`) on the simulator's clock: an ``SM``/``XM`` move
takes its own milliseconds, an ``SP`` its delay argument.

Motion commands (``SM``, ``XM``, ``SP``, ``TP``) go through the board's motion FIFO: one waits
while a move executes, and the board reads nothing more, and answers nothing, until the FIFO
has room; then it answers ``OK``.  So a sender that waits for each ``OK`` is paced by the motors.
Other commands are answered at once: ``EM``, ``SC``, ``CS`` ``OK``; ``V`` the firmware version
(one line, no ``OK``); ``QM`` ``QM,<command executing>,<motor 1 moving>,<motor 2 moving>,<FIFO
not empty>`` (no ``OK``); ``QG`` the status byte in hex (bit 0 FIFO not empty, 1 and 2 motor 2
and 1 moving, 3 a command executing, 4 pen up; no ``OK``); ``QP`` ``1`` pen up or ``0`` then
``OK``; ``QS`` the step counts then ``OK``; ``ES`` (emergency stop) ends the move in progress,
empties the FIFO and answers ``<interrupted>,<steps not taken 1>,<2>,<queued 1>,<2>`` then ``OK``
(the pen stays where it is).  An unknown command or bad arguments answer ``!8 Err: ...``.

Faults (:mod:`foldfab.sim.options`): ``error_at`` N answers command N with ``!<error_code>
Err: ...`` (default 8) and does not execute it; noise, stalls, ``mute``, ``disconnect_after`` and
``power_cycle`` act on the wire as for the other simulators.
"""

from __future__ import annotations

import dataclasses
import re
from typing import TYPE_CHECKING

import numpy as np

from foldfab.programs.machine import Interpretation
from foldfab.programs.read_ebb import EbbMachine, parse_command
from foldfab.sim.device import Simulator
from foldfab.sim.motion import Timed

if TYPE_CHECKING:
    from foldfab.devices import DeviceProfile
    from foldfab.programs.machine import Stroke
    from foldfab.programs.read_ebb import EbbCommand
    from foldfab.sim.options import SimOptions

VERSION = "EBBv13_and_above EB Firmware Version 2.8.1"
FIFO = 1
"""Motion commands the board holds besides the one executing (firmware 2.x)."""
MOTION = frozenset({"SM", "XM", "SP", "TP", "HM"})
COMMAND_LIMIT = 64
"""Bytes a command may have before the board gives up on it."""


class TimedEbb(Timed, EbbMachine):
    """The EBB machine with every move, pen lift and rest as a timed block."""

    def __init__(self, device, frame, known):
        super().__init__(device, frame, known)
        self.delay = 0.0  # seconds the SP being executed holds the FIFO

    def lift_duration(self) -> float:
        return self.delay

    def pen(self, command: EbbCommand) -> None:
        """``SP``/``TP``: the pen moves, and the FIFO waits for its delay even if it was there."""
        args = command.args
        self.delay = args[1] / 1000 if command.name == "SP" and len(args) > 1 and args[1] > 0 else 0.0
        before = len(self.result.strokes), self.stroke is not None
        self.execute(command)
        if (len(self.result.strokes), self.stroke is not None) == before and self.delay:
            self._emit(self.delay, self.position, 0.0)

    def timed_step(self, command: EbbCommand) -> None:
        """``SM``/``XM``: the move takes its milliseconds (a rest too); ``HM`` its steps at its rate."""
        start, start_motors = self.position, list(self.motors)
        self.execute(command)
        seconds = command.args[0] / 1000
        if command.name == "HM":  # the motor with more steps to go runs at the rate
            m1, m2 = (abs((a - b) * 1.0) for a, b in zip(start_motors, self.motors))
            seconds = max(m1, m2) / command.args[0]
        length = abs(complex(*self.position) - complex(*start)) / self.device.units_per_mm
        self._emit(seconds, start, length / seconds if seconds else 0.0)


class EbbBoard(Simulator):
    """Simulated EiBotBoard."""

    protocol = "ebb"
    TERMINATOR = "\r\n"
    SPECIAL = re.compile(rb"(?!)")  # nothing bypasses the command reader
    COMPLETES = re.compile(rb"\r")

    def __init__(self, device: DeviceProfile, options: SimOptions):
        super().__init__(device, options)
        self.waiting: EbbCommand | None = None  # a motion command waiting for FIFO room
        self.count = 0
        self.previous: list[Stroke] = []  # drawn before an emergency stop
        self.machine = self._new_machine(None)

    def _new_machine(self, motors: list[int] | None) -> TimedEbb:
        machine = TimedEbb(self.device, self.frame, None)
        if motors is not None:
            machine.motors = list(motors)
            m1, m2 = motors
            machine.position = machine.travel_from = ((m1 + m2) / 2, (m1 - m2) / 2)
        machine.start_timing(self._enqueue)
        return machine

    def interpretation(self) -> Interpretation:
        return Interpretation("ebb", strokes=self.strokes, travels=self.machine.sheet_travels())

    def _drawn(self) -> list[Stroke]:
        mark = self.planner[0].mark if self.planner else self.machine.mark()
        return self.previous + self.machine.strokes_at(mark)

    def _hungry(self) -> bool:
        return not self.frozen and self.waiting is None

    def _work(self) -> None:
        while not self.frozen:
            if self.waiting is not None:
                if len(self.planner) > FIFO:
                    return
                command, self.waiting = self.waiting, None
                self._motion(command)
                continue
            line = self._read_line()
            if line is None:
                if len(self.line) > COMMAND_LIMIT:
                    self._error(f"command too long ({len(self.line)} bytes)")
                    self.line.clear()
                return
            raw, start, _ = line
            raw = raw.strip("\n ")
            if raw:
                self._command(parse_command(raw[:COMMAND_LIMIT], start))

    def _command(self, command: EbbCommand) -> None:
        self.count += 1
        self.stats.commands += 1
        self.stats.last_activity = self.t
        name, args = command.name, command.args
        if self.count == self.options.error_at:
            self._error("injected fault", self.options.error_code or 8)
        elif command.error:
            self._error(f"bad parameter '{name}'")
        elif name in MOTION:
            if name in ("SM", "XM", "HM") and (len(args) < 2 - (name == "HM") or args[0] <= 0) or name == "SP" and (
                    not args or args[0] not in (0, 1)):
                self._error(f"bad parameter '{name}'")
            else:
                self.waiting = command
        elif name in ("EM", "SC", "CS"):
            self.reply("OK")
        elif name == "V":
            self.reply(VERSION)
        elif name == "QM":
            self.reply("QM,{0},{1},{1},{2}".format(int(bool(self.planner)), int(self.block_end is not None),
                                                   int(len(self.planner) > 1)))
        elif name == "QG":
            moving = self.block_end is not None
            self.reply(f"{(len(self.planner) > 1) | 6 * moving | 8 * bool(self.planner) | 16 * self._pen_up():02X}")
        elif name == "QP":
            self.reply(str(int(self._pen_up())))
            self.reply("OK")
        elif name == "QS":
            m1, m2 = self.machine.motors
            self.reply(f"{m1},{m2}")
            self.reply("OK")
        elif name == "ES":
            self._emergency_stop()
        else:
            self._error(f"Unknown command '{name}'")

    def _motion(self, command: EbbCommand) -> None:
        self.machine.at = command.offset
        if command.name in ("SP", "TP"):
            self.machine.pen(command)
        else:
            self.machine.timed_step(command)
        self.reply("OK")

    def _pen_up(self) -> bool:
        return self.machine.stroke is None

    def _emergency_stop(self) -> None:
        """ES: the move in progress ends where the carriage is, the FIFO is emptied."""
        (x, y), block = self.head()
        interrupted = int(block is not None)
        queued = max(len(self.planner) - 1, 0)
        down = self.machine.stroke is not None
        self.previous = self.strokes
        if block is not None and block.feed and down and self.previous:  # drawn up to where it stopped
            last = self.previous[-1]
            here = self.frame.to_sheet([(x, y)])
            self.previous[-1] = dataclasses.replace(last, points=np.vstack([last.points, here]))
        self.machine = self._new_machine([round(x + y), round(x - y)])
        if down:  # the pen stays down: what follows draws from here
            self.machine.lower_pen(self.base)
        self.position = self.machine.position
        self._clear_planner()
        self.waiting = None
        self.reply(f"{interrupted},0,0,{queued},0")
        self.reply("OK")

    def _error(self, text: str, code: int = 8) -> None:
        self.reply(f"!{code} Err: {text}")
        self.stats.errors.append(f"!{code}")

    def _idle_kind(self) -> str:
        home = self.machine.motors == [0, 0] and self._pen_up() and self.machine.result.strokes
        return "parked (pen up at home)" if home else "starved"
