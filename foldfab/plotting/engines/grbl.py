"""The GRBL engine: character counting, status polls, M0 holds, position checks at rest.

GRBL 1.1 (:class:`GrblSender`): the ``Grbl 1.1`` banner is awaited; without one after
:data:`BANNER_WAIT` seconds a soft reset (0x18) provokes it.  Lines go by character
counting (at most 127 bytes unacknowledged, ``\\n`` endings as in the program).  ``?``
polls the status at most 5 times a second, for progress and to know when motion has
really finished (``Idle`` in a report asked after the last ``ok``).  ``error:N`` and
``ALARM:N`` stop the job, with the program line and the meaning of N.  ``M0`` holds the
machine: once it reports ``Hold``, the operator is asked and ``~`` resumes.  At such a hold
and at the end, at rest, the status report's position (``MPos`` less ``WCO``, or ``WPos``)
must be the interpreter's within :data:`GRBL_POSITION_TOLERANCE`, else the job stops as
after an error, with the last check that agreed as its resume point.  GRBL says
``ok`` when a line enters its planner, so the executed count is conservative: lines
before a dwell or ``M`` synchronisation, or before the last :data:`PLANNER_BLOCKS`
motion lines; after a stop it is refined by the position where the machine held.

A laser job (a profile with ``[gcode] tool = "laser"``) runs only on a board in laser mode:
before the first line, ``$$`` must report ``$32=1`` (without it ``M4``/``M5`` and every power
change stop motion, the beam burns holes at each stop and stays on during rapids) and ``$30``
equal to the profile's ``spindle_max`` (else every power would be wrong).  The program switches
the beam off (``M5``) at its pauses and its end; a stop (a cancel, a fault, a signal) is the
feed hold, the soft reset (which switches the spindle off) and the program's preamble, whose
``M5`` switches the beam off once more.
"""

from __future__ import annotations

import bisect
import math
import re
import time
from collections import deque
from dataclasses import dataclass
from typing import Callable

from foldfab.errors import FoldfabError
from foldfab.plotting.engines.base import POLL, PenPosition, Sender, _Fault

GRBL_RX_BUFFER = 127
"""Bytes GRBL 1.1 may hold unacknowledged (its 128-byte receive buffer keeps one free)."""
PLANNER_BLOCKS = 16
"""GRBL's planner holds 15 motion blocks besides the one executing: lines acknowledged
after the 16th-last motion line may not have moved the machine yet."""
STATUS_INTERVAL = 0.2
"""At most 5 status queries a second, on the plotter's clock (a simulator's ``instant`` time
runs ahead while the host waits, so a host-clock cadence would leave it unasked for long
stretches of plotter time and its end would be seen late)."""
GRBL_POSITION_TOLERANCE = 0.02
"""mm a GRBL status position may differ from the program's: a step (80 steps/mm) and the
report's rounding."""
BANNER_WAIT = 2.5
"""Seconds to wait for the GRBL banner (an Arduino boots in about 2 s), before and after
the soft reset."""

GRBL_ERRORS = {
    1: "G-code words consist of a letter and a value. Letter was not found.",
    2: "Missing the expected G-code word value or numeric value format is not valid.",
    3: "Grbl '$' system command was not recognized or supported.",
    4: "Negative value received for an expected positive value.",
    5: "Homing cycle failure. Homing is not enabled via settings.",
    6: "Minimum step pulse time must be greater than 3usec.",
    7: "An EEPROM read failed. Auto-restoring affected EEPROM to default values.",
    8: "Grbl '$' command cannot be used unless Grbl is IDLE.",
    9: "G-code commands are locked out during alarm or jog state.",
    10: "Soft limits cannot be enabled without homing also enabled.",
    11: "Max characters per line exceeded. Received command line was not executed.",
    12: "Grbl '$' setting value cause the step rate to exceed the maximum supported.",
    13: "Safety door detected as opened and door state initiated.",
    14: "Build info or startup line exceeded EEPROM line length limit. Line not stored.",
    15: "Jog target exceeds machine travel. Jog command has been ignored.",
    16: "Jog command has no '=' or contains prohibited g-code.",
    17: "Laser mode requires PWM output.",
    20: "Unsupported or invalid g-code command found in block.",
    21: "More than one g-code command from same modal group found in block.",
    22: "Feed rate has not yet been set or is undefined.",
    23: "G-code command in block requires an integer value.",
    24: "More than one g-code command that requires axis words found in block.",
    25: "Repeated g-code word found in block.",
    26: "No axis words found in block for g-code command or current modal state which requires them.",
    27: "Line number value is invalid.",
    28: "G-code command is missing a required value word.",
    29: "G59.x work coordinate systems are not supported.",
    30: "G53 only allowed with G0 and G1 motion modes.",
    31: "Axis words found in block when no command or current modal state uses them.",
    32: "G2 and G3 arcs require at least one in-plane axis word.",
    33: "Motion command target is invalid.",
    34: "Arc radius value is invalid.",
    35: "G2 and G3 arcs require at least one in-plane offset word.",
    36: "Unused value words found in block.",
    37: "G43.1 dynamic tool length offset is not assigned to configured tool length axis.",
    38: "Tool number greater than max supported value.",
}
"""GRBL 1.1 ``error:N`` meanings (gnea/grbl doc/csv/error_codes_en_US.csv)."""

GRBL_ALARMS = {
    1: "Hard limit triggered. Machine position is likely lost; re-homing is highly recommended.",
    2: "Soft limit: G-code motion target exceeds machine travel. Machine position retained.",
    3: "Reset while in motion. Machine position is likely lost; re-homing is highly recommended.",
    4: "Probe fail: the probe is not in the expected initial state.",
    5: "Probe fail: the probe did not contact the workpiece within the programmed travel.",
    6: "Homing fail: the active homing cycle was reset.",
    7: "Homing fail: safety door was opened during homing cycle.",
    8: "Homing fail: pull off travel failed to clear limit switch.",
    9: "Homing fail: could not find limit switch within search distances.",
}
"""GRBL 1.1 ``ALARM:N`` meanings (gnea/grbl doc/csv/alarm_codes_en_US.csv)."""


@dataclass
class _Line:
    """One program line: bytes ``start..end`` (``data`` ends in ``\\n``), numbered from 1."""

    start: int
    end: int
    number: int
    data: bytes
    motion: bool
    """It moves the machine (X, Y or Z words): it may sit in GRBL's planner."""
    sync: bool
    """GRBL executes it only once the planner is empty (G4, M0, M2, M3, M5, M30)."""


_STATUS = re.compile(r"<([A-Za-z]+)(?::(\d+))?(.*)>")
_SETTING = re.compile(r"\$(\d{1,3})=(-?\d{1,9}(?:\.\d{0,6})?)")
"""A ``$$`` line, ``$N=value``: a setting number and a bounded decimal."""
_FIELD = re.compile(r"\|(MPos|WPos|WCO):([-\d.]+),([-\d.]+),([-\d.]+)")


class GrblSender(Sender):
    """GRBL 1.1: banner, character counting, status polling, M0 holds."""

    def __init__(self, *args):
        super().__init__(*args)
        self.lines_ = self.split()
        self.pending: deque[_Line] = deque()  # sent, not answered
        self.in_rx = 0  # bytes of pending lines
        self.answered = 0  # program lines answered (ok or error): the next one's index
        self.ceiling = len(self.data)  # executed can never pass an unexecuted (error) line
        self.state, self.substate = "", None
        self.machine_position: tuple[float, float, float] | None = None
        self.position_kind = "MPos"
        self.wco = (0.0, 0.0, 0.0)
        self.last_query = -math.inf  # plotter clock
        self.query_answered = 0  # lines answered when the outstanding "?" was sent
        self.querying = False
        self.unanswered_since: float | None = None  # the first "?" still without a report
        self.report: tuple[str, int] | None = None  # (state, lines answered when it was asked)
        self.banner = ""
        self.pause_ends = {p.offset: p for p in self.program.pauses}
        self.moves = [i for i, line in enumerate(self.lines_) if line.motion]
        self.syncs = [i for i, line in enumerate(self.lines_) if line.sync]
        self.verified = 0  # program offset of the last position check that agreed
        self.expecting: tuple[object, int] | None = None  # (interpreter, lines it has read)
        self.settings: dict[int, float] = {}  # the board's $$ report

    def split(self) -> list[_Line]:
        """The program's lines with their byte ranges and what GRBL does with them."""
        from foldfab.programs.read_gcode import read_gcode_line

        lines, start = [], 0
        text = self.program.text
        for number, raw in enumerate(text.split("\n"), 1):
            if start >= len(text):
                break
            end = min(start + len(raw) + 1, len(text))
            data = raw.encode("ascii") + b"\n"
            if len(data) > GRBL_RX_BUFFER:
                raise FoldfabError(f"program line {number} is {len(data)} bytes long; GRBL takes "
                                   f"lines of at most {GRBL_RX_BUFFER} bytes")
            words = read_gcode_line(raw, start).words
            letters = {letter for letter, _ in words}
            sync = any((letter, value) in (("G", 4), ("M", 0), ("M", 2), ("M", 3), ("M", 4), ("M", 5), ("M", 30))
                       for letter, value in words)
            lines.append(_Line(start, end, number, data, bool(letters & {"X", "Y", "Z"}), sync))
            start = end
        return lines

    # -- replies ---------------------------------------------------------------------------
    def pump(self) -> None:
        """Ask the status when due, wait up to POLL for replies, handle them."""
        now, plotter_now = time.monotonic(), self.clock()
        since = plotter_now - self.last_query
        if since >= STATUS_INTERVAL and (not self.querying or since > 1.0):
            self.write(b"?")
            self.last_query, self.querying, self.query_answered = plotter_now, True, self.answered
            if self.unanswered_since is None:
                self.unanswered_since = now
        elif (self.unanswered_since is not None and not self.stopping and not self.inbox  # (a reply arriving)
              and now - self.unanswered_since > self.stall_timeout):
            raise _Fault(f"GRBL stopped answering: no status report for {self.stall_timeout:g} s "
                         "(hung, or the cable is loose?)")
        self.receive(wait=True)
        for reply in self.lines():
            self.handle(reply)
        self.tick()

    def handle(self, reply: str) -> None:
        """Act on one line from GRBL."""
        if reply == "ok":
            if self.pending:
                line = self.pending.popleft()
                self.in_rx -= len(line.data)
                if line.number:
                    self.answered += 1
                self.alive = time.monotonic()
                self.update_acked()
        elif reply.startswith("error:"):
            line = self.pending.popleft() if self.pending else None
            if line is not None:
                self.in_rx -= len(line.data)
            code = reply[6:].strip()
            meaning = GRBL_ERRORS.get(int(code), "unknown error") if code.isdigit() else "unknown error"
            where = f" at program line {line.number} ({line.data.decode().strip()!r})" \
                if line is not None and line.number else ""
            if line is not None and line.number:  # answered, not executed
                self.answered += 1
                self.ceiling = min(self.ceiling, line.start)
            if not self.stopping:
                raise _Fault(f"GRBL error {code}{where}: {meaning}", suspect=True)
        elif reply.startswith("ALARM:"):
            code = reply[6:].strip()
            meaning = GRBL_ALARMS.get(int(code), "unknown alarm") if code.isdigit() else "unknown alarm"
            self.state = "Alarm"
            if not self.stopping:
                raise _Fault(f"GRBL alarm {code}: {meaning}")
        elif reply.startswith("<"):
            self.status(reply)
        elif reply.startswith("$"):
            match = _SETTING.fullmatch(reply)
            if match is None:
                raise _Fault(f"unreadable setting from GRBL: {reply[:40]!r} (line noise?)")
            self.settings[int(match.group(1))] = float(match.group(2))
        elif reply.startswith("Grbl "):
            self.banner = reply
            if not self.stopping:
                raise _Fault(f"GRBL reset itself during the job ({reply!r}): the lines it held are lost")
        elif not reply.startswith("["):
            raise _Fault(f"unexpected reply from GRBL: {reply!r} (line noise, or the wrong baud rate?)")

    def status(self, reply: str) -> None:
        match = _STATUS.match(reply)
        if not match:
            raise _Fault(f"unreadable status report from GRBL: {reply!r}")
        if (match.group(1), match.group(2)) != (self.state, self.substate):
            self.alive = time.monotonic()
        self.state, self.substate = match.group(1), match.group(2)
        for kind, *values in _FIELD.findall(match.group(3)):
            point = tuple(float(v) for v in values)
            if kind == "WCO":
                self.wco = point
            else:
                if point != self.machine_position:
                    self.alive = time.monotonic()
                self.machine_position, self.position_kind = point, kind
        if self.querying:
            self.querying, self.unanswered_since = False, None
            self.report = (self.state, self.query_answered)
        if self.idle():
            self.acked = max(self.acked, min(self.lines_[self.answered - 1].end, self.ceiling)
                             if self.answered else 0)

    def idle(self) -> bool:
        """A report asked after every line was answered says Idle: motion has finished."""
        return not self.pending and self.report == ("Idle", self.answered)

    def work_position(self) -> tuple[float, float, float] | None:
        if self.machine_position is None or self.position_kind == "WPos":
            return self.machine_position
        return tuple(p - o for p, o in zip(self.machine_position, self.wco))

    def update_acked(self) -> None:
        """Lines before a synchronising line, or before the planner's reach, are executed."""
        moves = bisect.bisect_left(self.moves, self.answered)  # motion lines answered
        safe = self.moves[moves - PLANNER_BLOCKS] if moves >= PLANNER_BLOCKS else 0
        syncs = bisect.bisect_left(self.syncs, self.answered)
        if syncs:
            safe = max(safe, self.syncs[syncs - 1])
        offset = self.lines_[safe].start if safe < len(self.lines_) else len(self.data)
        self.acked = max(self.acked, min(offset, self.ceiling))

    def wait(self, condition: Callable[[], bool], what: str, patience: float) -> None:
        """Pump replies until ``condition``; a _Fault after ``patience`` s without progress."""
        self.alive = time.monotonic()
        while not condition():
            if self.stalled(patience):
                raise _Fault(f"GRBL stalled: no progress for {patience:.0f} s while waiting for "
                             f"{what} (on hold, jammed or hung?)")
            self.pump()

    # -- the job ---------------------------------------------------------------------------
    def connect(self) -> None:
        """Wait for the banner; if none comes, a soft reset brings one (CONVENTIONS.md)."""
        for attempt in range(2):
            deadline = time.monotonic() + BANNER_WAIT
            while not self.banner and time.monotonic() < deadline:
                self.receive(wait=True)
                self.banner = next((r for r in self.lines() if r.startswith("Grbl ")), "")
            if self.banner or attempt:
                break
            self.write(b"\x18")
        if not self.banner:
            raise _Fault(f"no GRBL banner from {self.device.name}, even after a soft reset (0x18): "
                         "is it a GRBL 1.1 board, switched on, at the profile's baud rate?")
        if not self.banner.startswith("Grbl 1.1"):
            raise FoldfabError(f"{self.device.name} answers {self.banner.split('[')[0].strip()!r}; "
                               "foldfab speaks GRBL 1.1")
        self.stopping = True  # the banner may come with [MSG:...] and ALARM lines
        try:
            self.wait(lambda: self.report is not None, "a status report", self.stall_timeout)
        finally:
            self.stopping = False
        if self.state == "Alarm":
            raise FoldfabError(f"{self.device.name} is in alarm state: home it ($H) or unlock it "
                               "($X), then plot again")

    def locate(self) -> PenPosition | None:
        """See :func:`foldfab.plotting.stream.locate_pen`."""
        timeout = self.port.timeout
        self.port.timeout = POLL
        self.stopping = True  # replies to the lost host (ok, error) are not this job's faults
        try:
            deadline = time.monotonic() + BANNER_WAIT
            while time.monotonic() < deadline:
                self.receive(wait=True)
                if any(reply.startswith("Grbl ") for reply in self.lines()):
                    return None  # it rebooted: its position is gone
            if isinstance(self.device.gcode.pen_up, str):
                return None
            # At rest: idle, or in a feed hold that has come to a stop (a stop whose lifting
            # was itself interrupted leaves the board so); an alarm says its position may be lost.
            self.wait(lambda: self.report is not None and (self.report[0] in ("Idle", "Alarm") or (
                self.report[0] == "Hold" and self.substate in (None, "0"))),
                      "the end of the lines it held", self.stall_timeout)
            if self.state == "Alarm":
                return None
            held = self.state == "Hold"
            self.banner = ""
            self.write(b"\x18")
            self.wait(lambda: bool(self.banner), "the soft reset", self.stall_timeout)
            self.next_report()
            if held and self.state == "Alarm":
                # GRBL alarms at a reset in a feed hold (ALARM:3) though the motion was over and
                # the position kept, as when a stop lifts the tool (lift): unlock it the same way.
                self.send_line(b"$X\n")
                self.next_report()
            if self.state == "Alarm" or self.machine_position is None:
                return None
            from foldfab.programs.read_gcode import GcodeMachine

            x, y, z = self.work_position()
            machine = GcodeMachine(self.device, self.device.frame(self.device.sheet), None)
            return PenPosition(x, y, machine.down_limit is not None and z <= machine.down_limit)
        except _Fault as exc:
            raise FoldfabError(str(exc)) from None
        finally:
            self.port.timeout = timeout

    def check_laser_mode(self) -> None:
        """A laser job: refuse a board whose ``$$`` does not say laser mode (``$32=1``) and the
        profile's ``$30``."""
        self.settings.clear()
        self.send_line(b"$$\n")
        name, mode, top = self.device.name, self.settings.get(32), self.settings.get(30)
        if mode != 1:
            found = "does not report $32" if mode is None else f"has $32={mode:g}"
            raise FoldfabError(
                f"{name} {found}: GRBL's laser mode is off, so M4/M5 and every power change would stop "
                "the head and burn a hole, and the beam would stay on during rapids; send $32=1 to the "
                "board (it keeps the setting), then plot again")
        full = self.device.gcode.spindle_max
        if top is None or abs(top - full) > 0.5:
            raise FoldfabError(
                f"{name} reports $30={'nothing' if top is None else f'{top:g}'} but its profile "
                f"{self.device.source} says spindle_max = {full:g}: every power would be wrong; send "
                f"$30={full:g} to the board or correct spindle_max, then plot again")

    def send_program(self) -> None:
        self.connect()
        if self.device.laser:
            self.check_laser_mode()
        index = 0
        while index < len(self.lines_):
            self.check_cancel()
            line = self.lines_[index]
            self.wait(lambda: self.in_rx + len(line.data) <= GRBL_RX_BUFFER,
                      "room in its receive buffer", self.patience(self.acked, line.end))
            batch = [line]  # as many lines as fit, in one write
            while (index + len(batch) < len(self.lines_) and batch[-1].end not in self.pause_ends
                   and self.in_rx + sum(len(b.data) for b in batch)
                   + len(self.lines_[index + len(batch)].data) <= GRBL_RX_BUFFER):
                batch.append(self.lines_[index + len(batch)])
            self.write(b"".join(b.data for b in batch))
            self.pending.extend(batch)
            self.in_rx += sum(len(b.data) for b in batch)
            self.sent = batch[-1].end
            index += len(batch)
            pause = self.pause_ends.get(self.sent)
            if pause is not None:
                self.hold_for(pause.message, index - 1)
        self.wait(self.idle, "the end of motion", self.patience(self.acked, len(self.data)))
        self.check_position(len(self.lines_) - 1, len(self.data))

    def check_position(self, index: int, offset: int) -> None:
        """At rest after program line ``index``: the status report's position must be the
        program's (by the interpreter), else a fault; ``offset`` is then verified."""
        from foldfab.programs.read_gcode import GcodeMachine, read_gcode_line

        if not self.lines_ or self.machine_position is None:
            return
        if self.expecting is None:
            self.expecting = (GcodeMachine(self.device, self.device.frame(self.device.sheet), None), 0)
        machine, read = self.expecting
        for line in self.lines_[read:index + 1]:
            machine.apply(read_gcode_line(line.data.decode("ascii")[:-1], line.start), line.end)
        self.expecting = (machine, max(read, index + 1))
        expected = (*machine.position, machine.z)
        actual = self.work_position()
        axes = 2 if machine.servo else 3  # a servo pen's state is not in the position
        if any(abs(a - e) > GRBL_POSITION_TOLERANCE for a, e in zip(actual[:axes], expected[:axes])):
            self.ceiling = min(self.ceiling, self.verified)
            self.acked = min(self.acked, self.verified)
            raise self.misplaced((*actual[:axes], None), (*expected[:axes], None), "mm", offset)
        self.verified = offset

    def hold_for(self, message: str, index: int) -> None:
        """M0 was sent: once GRBL holds there (motion done), ask the operator, then ``~``."""
        self.wait(lambda: len(self.pending) == 1 and self.report is not None and
                  self.report[0] == "Hold" and self.substate in (None, "0") and
                  self.report[1] == self.answered,
                  "the M0 pause", self.patience(self.acked, self.sent))
        self.check_position(index, self.lines_[index].start)
        self.acked = max(self.acked, self.lines_[index].start)
        self.ask_operator(message)
        self.write(b"~")
        self.wait(lambda: not self.pending, "the end of the pause", self.stall_timeout)

    def lift(self, suspect: bool) -> str:
        """Feed hold, soft reset, then the program's preamble (units, modes, tool up)."""
        self.write(b"!")
        self.report = None
        try:
            self.wait(lambda: self.report is not None and self.report[0] in ("Hold", "Idle", "Alarm"),
                      "the feed hold", self.stall_timeout + 2 * BANNER_WAIT)
            self.refine_acked()
        except _Fault:
            pass
        self.banner = ""
        self.write(b"\x18")
        deadline = time.monotonic() + 2 * BANNER_WAIT
        while not self.banner and time.monotonic() < deadline:
            self.receive(wait=True)
            for reply in self.lines():
                self.handle(reply)
        if not self.banner:
            raise _Fault("GRBL did not answer the soft reset")
        self.pending.clear()
        self.in_rx = 0
        self.next_report()
        note = ""
        if self.state == "Alarm":
            self.send_line(b"$X\n")
            note = ("GRBL raised an alarm at the reset and was unlocked ($X) to lift the tool; "
                    "home it before resuming if its position may be lost")
        for raw in self.program.text[:self.program.sections[0].offset].split("\n"):
            from foldfab.programs.read_gcode import read_gcode_line

            if read_gcode_line(raw).words:
                self.send_line(raw.encode("ascii") + b"\n")
        return note

    def next_report(self) -> None:
        """Forget the last status report and wait for the next one (after a reset or ``$X``)."""
        self.report = None
        self.wait(lambda: self.report is not None, "a status report", self.stall_timeout)

    def send_line(self, data: bytes) -> None:
        """Send one line that is not part of the program and wait for its answer."""
        self.write(data)
        self.pending.append(_Line(self.sent, self.sent, 0, data, False, False))
        self.in_rx += len(data)
        self.wait(lambda: not self.pending, repr(data.decode().strip()), self.stall_timeout)

    def refine_acked(self) -> None:
        """After a hold: the first answered line whose move passes through the held position
        is the one that was executing; every line before it was executed."""
        from foldfab.programs.read_gcode import GcodeMachine, read_gcode_line

        held = self.work_position()
        first = next((i for i, line in enumerate(self.lines_) if line.end > self.acked), None)
        if held is None or first is None or first >= self.answered:
            return
        machine = GcodeMachine(self.device, self.device.frame(self.device.sheet), None)
        before = None
        for i, line in enumerate(self.lines_[:self.answered]):
            machine.apply(read_gcode_line(line.data.decode("ascii")[:-1], line.start), line.end)
            after = (*machine.position, machine.z if not machine.servo else 0.0)
            if i >= first and before is not None and _on_segment(held, before, after):
                self.acked = max(self.acked, min(line.start, self.ceiling))
                return
            before = after


def _on_segment(point, a, b, tolerance: float = 0.01) -> bool:
    """Is ``point`` on the segment ``a``..``b`` (3D, within ``tolerance``)?"""
    d = [e - s for s, e in zip(a, b)]
    length2 = sum(c * c for c in d)
    t = 0.0 if length2 == 0 else max(0.0, min(1.0, sum((p - s) * c for p, s, c in zip(point, a, d)) / length2))
    return sum((s + t * c - p) ** 2 for p, s, c in zip(point, a, d)) <= tolerance ** 2
