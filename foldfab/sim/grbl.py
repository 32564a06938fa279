"""A simulated GRBL 1.1 controller (as gnea/grbl ``protocol.c``, ``serial.c``, ``report.c``).

* Serial: a 128-byte ring buffer that holds 127 bytes; what arrives when it is full
  is lost.  Realtime bytes never enter it and get no ``ok``: ``?`` status report,
  ``!`` feed hold, ``~`` cycle start / resume (also after ``M0``), 0x18 soft reset;
  any byte above 0x7F is dropped (GRBL's extended realtime range).
* Lines end at ``\\n`` or ``\\r`` (so ``\\r\\n`` gives an extra ``ok`` for the empty
  line).  Comments and whitespace do not count; a line keeping more than 79
  characters answers ``error:11`` (line overflow).  Each line gets ``ok`` when it has
  been executed: a motion line when its moves are in the planner (16 blocks, one kept
  free), so a sender that waits for ``ok`` sees the planner fill; ``G4`` after its
  dwell; ``M0`` only after the ``~`` that ends the pause; ``M0``, ``M2``, ``M3``,
  ``M5`` and ``G4`` first wait until the planner is empty.
* Errors: ``error:1`` text that is not a word, ``error:2`` a letter without a number,
  ``error:20`` unsupported G/M words, ``error:9`` G-code while in alarm, ``error:3``
  unknown ``$`` command, ``error:5`` ``$H`` (homing is off); ``error_at=N`` makes line
  N (counting every line) answer ``error:<error_code>`` (default 20) unexecuted.
* A soft reset flushes the buffer, the line and the planner, answers ``ALARM:3`` if
  the machine was moving (position lost; G-code then answers ``error:9`` until
  ``$X``), and prints the banner (plus ``[MSG:'$H'|'$X' to unlock]`` in alarm).  The
  parser restarts with its defaults, but a Z tool stays where it is: down if it was
  (a servo pen is switched off with the spindle output).
* ``$X``, ``$``, ``$I``, ``$G`` and ``$$`` answer as GRBL does (settings from the profile).
* Laser mode (GRBL's ``doc/markdown/laser_mode.md``, ``gcode.c``): ``$30``/``$31`` are a laser
  profile's ``spindle_max``/``spindle_min``, ``$32`` the ``laser_mode`` option (default: 1 for a
  laser profile).  ``M3``/``M4`` switch the beam on, ``M5``, ``M2`` and a soft reset off; with
  ``$32=1`` it burns only on ``G1`` moves with ``S`` above 0, and an ``S`` change on a move does
  not stop motion; with ``$32=0`` it burns on ``G0`` moves too and every ``S`` change waits for
  the planner to empty (the machine stops).  A change of spindle state (``M3``/``M4``/``M5``)
  always waits, as in GRBL.  Each recorded stroke carries its power.
* Status: ``<Idle|MPos:x,y,z|FS:feed,spindle>`` with state ``Idle``, ``Run``,
  ``Hold:0`` or ``Alarm``; the position is interpolated along the current move.
  ``WCO``/``Ov`` fields, ``Hold:1`` deceleration, jogging, homing and check mode are
  not simulated.
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING

from foldfab.programs.machine import Interpretation
from foldfab.programs.read_gcode import GcodeLine, read_gcode_line
from foldfab.sim.device import Simulator
from foldfab.sim.motion import Block, Point, TimedGcode
from foldfab.sim.record import PauseRecord

if TYPE_CHECKING:
    from foldfab.devices import DeviceProfile
    from foldfab.programs.machine import Stroke
    from foldfab.sim.options import SimOptions

BANNER = "\r\nGrbl 1.1h ['$' for help]"
LINE_BUFFER = 80  # LINE_BUFFER_SIZE: 79 characters + terminator
SYNC_M = (0, 2, 3, 4, 5)  # M words that wait for the planner to empty (G4 too)
HELP = "[HLP:$$ $# $G $I $N $x=val $Nx=line $J=line $SLP $C $X $H ~ ! ? ctrl-x]"


class GrblController(Simulator):
    """Simulated GRBL 1.1 board."""

    protocol = "gcode"
    TERMINATOR = "\r\n"
    RING_SLACK = 1
    SPECIAL = re.compile(rb"[?!~\x18\x80-\xff]")
    COMPLETES = re.compile(rb"[\n\r]")

    def __init__(self, device: DeviceProfile, options: SimOptions):
        super().__init__(device, options)
        self.alarm = False
        self.waiting: tuple[GcodeLine, int] | None = None  # read, waits for the planner
        self.lines = 0
        self.ok_on_resume = False  # M0's ok is sent by the ~ that ends it
        self.dwelling = False  # G4: nothing is read until the dwell is over
        self.ended = False  # M2 executed, nothing since
        self.hold: PauseRecord | None = None
        self.z = device.gcode.pen_up if isinstance(device.gcode.pen_up, float) else 0.0
        self.laser_mode = device.laser if options.laser_mode is None else options.laser_mode
        """GRBL's ``$32``."""
        self.previous: list[Stroke] = []  # drawn before the last soft reset
        self.machine = self._new_machine((0.0, 0.0))

    def _new_machine(self, position: Point) -> TimedGcode:
        machine = TimedGcode(self.device, self.frame, None)
        machine.position = position
        machine.laser_mode = self.laser_mode
        machine.start_timing(self._enqueue)
        return machine

    def connect(self) -> None:
        if self.options.reset_on_open:
            self.soft_reset()

    def interpretation(self) -> Interpretation:
        return Interpretation("gcode", strokes=self.strokes, travels=self.machine.sheet_travels(),
                              pauses=list(self.machine.result.pauses))

    @property
    def beam(self) -> str | None:
        """The laser's spindle state, ``"M3"`` or ``"M4"``; None when it is off (``M5``)."""
        return self.machine.beam

    def _drawn(self) -> list[Stroke]:
        mark = self.planner[0].mark if self.planner else self.machine.mark()
        return self.previous + self.machine.strokes_at(mark)

    def _enqueue(self, block: Block) -> None:
        block.z = self.machine.z if not self.machine.servo else 0.0
        super()._enqueue(block)

    def _completed(self, block: Block) -> None:
        super()._completed(block)
        self.z = block.z

    def _hungry(self) -> bool:
        return not self.frozen and not self.dwelling and self.waiting is None

    # --- lines ----------------------------------------------------------------------------

    def _work(self) -> None:
        while not self.frozen and not self.dwelling:
            if self.waiting is not None:
                if not self._execute(*self.waiting):
                    return
                self.waiting = None
                continue
            line = self._read_line()
            if line is None:
                return
            self._line(*line)

    def _line(self, raw: str, start: int, end: int) -> None:
        self.lines += 1
        self.stats.commands += 1
        self.stats.last_activity = self.t
        line = read_gcode_line(raw, start)
        kept = sum(c > " " for c in line.code)
        if kept >= LINE_BUFFER:
            self._error(11)
        elif self.lines == self.options.error_at:
            self._error(self.options.error_code or 20)
        elif kept == 0:
            self.machine.apply(line, end)  # comment lines carry M0 messages
            self.reply("ok")
        elif line.code.lstrip().startswith("$"):
            self._system(line.code.replace(" ", ""))
        elif self.alarm:
            self._error(9)
        elif line.unreadable:
            self._error(2 if line.unreadable[0].isalpha() else 1)
        elif line.unsupported:
            self._error(20)
        else:
            self.waiting = (line, end)

    def _execute(self, line: GcodeLine, end: int) -> bool:
        """Execute a valid line if the planner lets it; False: not yet."""
        dwell = any(letter == "G" and value == 4 for letter, value in line.words)
        m_words = [value for letter, value in line.words if letter == "M"]
        if (dwell or any(m in SYNC_M for m in m_words) or self._power_sync(line)) and self.planner:
            return False
        if len(self.planner) >= self.options.planner - 1:
            return False
        self.machine.at = line.offset
        self.machine.apply(line, end)
        self.ended = 2 in m_words
        if dwell:
            seconds = next((value for letter, value in line.words if letter == "P"), 0.0)
            self.dwelling = True
            self._enqueue(Block(seconds, self.machine.position, self.machine.position, 0.0,
                                self.machine.mark(), done=self._dwelt))
        elif 0 in m_words:
            self._hold("M0")
            self.ok_on_resume = True
        elif self.ended:
            self.reply("[MSG:Pgm End]")
            self.reply("ok")
        else:
            self.reply("ok")
        return True

    def _power_sync(self, line: GcodeLine) -> bool:
        """Does an ``S`` word wait for the planner to empty?  GRBL syncs a change of spindle speed
        while the spindle is on, except in laser mode on a line that moves."""
        power = next((value for letter, value in line.words if letter == "S"), None)
        if power is None or power == self.machine.spindle or self.machine.beam is None:
            return False
        moves = any(letter in "XYZ" for letter, _ in line.words)
        return not (self.laser_mode and moves)

    def _dwelt(self) -> None:
        self.dwelling = False
        self.reply("ok")

    def _system(self, command: str) -> None:
        if command == "$X":
            if self.alarm:
                self.alarm = False
                self.reply("[MSG:Caution: Unlocked]")
        elif command == "$":
            self.reply(HELP)
        elif command == "$I":
            self.reply("[VER:1.1h.20190825:]")
            self.reply(f"[OPT:V,{self.options.planner - 1},{self.size}]")
        elif command == "$G":
            m = self.machine
            self.reply(f"[GC:{m.motion} G54 G17 G{20 if m.scale != 1 else 21} "
                       f"G{90 if m.absolute else 91} G94 {m.beam or 'M5'} M9 T0 "
                       f"F{(m.feed or 0) * 60:g} S{m.spindle:g}]")
        elif command == "$$":
            for line in self._settings():
                self.reply(line)
        elif command == "$H":
            self._error(5)
            return
        else:
            self._error(3)
            return
        self.reply("ok")

    def _settings(self) -> list[str]:
        """``$$``: GRBL's defaults with the profile's speeds, acceleration, junction deviation,
        reach and laser settings ($30 and $31 as GRBL prints them, in whole numbers)."""
        motion, (w, h) = self.device.motion, self.device.plottable_area
        z_rate = (self.device.gcode.z_speed or motion.travel_speed) * 60
        deviation = 0.010 if motion.junction_deviation is None else motion.junction_deviation
        values = {0: 10, 1: 25, 2: 0, 3: 0, 4: 0, 5: 0, 6: 0, 10: 1, 11: deviation, 12: 0.002,
                  13: 0, 20: 0, 21: 0, 22: 0, 30: round(self.device.gcode.spindle_max or 1000),
                  31: round(self.device.gcode.spindle_min), 32: int(self.laser_mode),
                  100: 250, 101: 250, 102: 250,
                  110: motion.travel_speed * 60, 111: motion.travel_speed * 60, 112: z_rate,
                  120: motion.acceleration, 121: motion.acceleration, 122: motion.acceleration,
                  130: w, 131: h, 132: 10}
        return [f"${key}={value:.3f}" if isinstance(value, float) else f"${key}={value}"
                for key, value in values.items()]

    def _error(self, code: int) -> None:
        self.reply(f"error:{code}")
        self.stats.errors.append(f"error:{code}")

    # --- realtime -------------------------------------------------------------------------

    def _special(self, byte: int) -> None:
        self._when_running(lambda: self._realtime(byte))

    def _realtime(self, byte: int) -> None:
        if byte == 0x18:
            self.soft_reset()
        elif byte == ord("?"):
            self.reply(self._status())
        elif byte == ord("!") and not self.alarm:
            self._hold("feed hold")
        elif byte == ord("~"):
            self._resume()
        # bytes above 0x7F: GRBL's extended realtime range, dropped here

    def _status(self) -> str:
        (x, y), block = self.head()
        if self.alarm:
            state = "Alarm"
        elif "hold" in self.frozen:
            state = "Hold:0"
        else:
            state = "Run" if self.planner else "Idle"
        z = block.z if block is not None else self.z
        feed = block.feed * 60 if block is not None and self.block_end is not None else 0.0
        return f"<{state}|MPos:{x:.3f},{y:.3f},{z:.3f}|FS:{feed:.0f},{self.machine.spindle:.0f}>"

    def _hold(self, reason: str) -> None:
        if "hold" not in self.frozen:
            self._freeze("hold")
            self.hold = PauseRecord(self.t, None, reason)
            self.stats.pauses.append(self.hold)

    def _resume(self) -> None:
        if "hold" not in self.frozen:
            return
        self.hold.duration = self.t - self.hold.start
        self.hold = None
        self._thaw("hold")
        if self.ok_on_resume:
            self.ok_on_resume = False
            self.reply("ok")

    def soft_reset(self) -> None:
        """0x18: stop, flush everything, greet again (ALARM:3 if it was moving)."""
        (x, y), block = self.head()
        if block is not None:
            self.alarm = True
            self.reply("ALARM:3")
            self.stats.alarms.append("ALARM:3")
            self.z = block.z
        self.previous = self.strokes
        self.machine = self._new_machine((x, y))
        if self.machine.down_limit is not None:  # the Z axis stays where it is: a tool that was down still is
            self.machine.z = self.z
            self.machine.pen_state(self.z <= self.machine.down_limit, self.z, self.base + len(self.rx))
        self.position = (x, y)
        if self.hold is not None:
            self.hold.duration = self.t - self.hold.start
            self.hold = None
        self.frozen.discard("hold")
        self._clear_planner()
        self._free(self.base + len(self.rx))
        self.line.clear()
        self.waiting, self.ok_on_resume, self.ended, self.dwelling = None, False, False, False
        self.reply(BANNER)
        if self.alarm:
            self.reply("[MSG:'$H'|'$X' to unlock]")

    def _idle_kind(self) -> str:
        return "ended" if self.ended else "starved"
