"""Stream a program to a plotter without losing a byte, and stop it safely.

Plotters have small receive buffers: a sender that writes faster than the plotter
draws overruns the buffer and commands are lost silently.  :func:`stream` sends a
:class:`~foldfab.programs.program.Program` over an open pyserial port with the handshake the
device profile's ``[buffer] flow_control`` names.

HP-GL (:class:`_HPGLSender`) sends whole commands (``;``-terminated) and never sends
past a pause:

* ``xonxoff``: foldfab reads XOFF (0x13) and XON (0x11) itself, so the handshake also
  holds where no driver does it (sockets, pseudo-terminals, ``--no-xonxoff``); writes
  are paced at the line rate so that at most :attr:`_HPGLSender.ahead` bytes are on the
  wire when XOFF comes (a pseudo-terminal's kernel buffer would otherwise hold kilobytes).
* ``rtscts``: ``port.cts`` is checked before every write (same pacing).
* ``escb``: ``ESC.B`` asks the free buffer space; at most that much is sent.
* ``none``: no handshake at all: at most one buffer is sent between two checkpoints.

A *checkpoint* writes ``OE;`` and waits for the answer.  An output instruction is
answered only when the plotter reaches it in its buffer, after the moves before it, so
the round trip drains the buffer with every flow control, and the answer is the error
register (cleared by reading): 0 means every command since the previous checkpoint was
understood.  At pauses, at the end (so a job is done only when its last check agreed) and
every :data:`VERIFY_EVERY` bytes (then on an inline marker, below, if one comes first: ``OE;OA;``)
the same round trip asks ``OA`` (``x,y,pen``), once the
program has placed the pen: a position more than a plotter unit from the interpreter's (or
another pen state) is line noise that kept the program valid (a digit turned into another)
or lost steps, and stops the job like a plotter error; a resume draws again from the last
check that agreed.  Checkpoints come at pauses, at the end and every :data:`CHECK_EVERY` bytes
(at most a buffer), so an error is found within that window and the executed count is
exact there; with ``escb`` the buffer is first drained by ``ESC.B`` polls, which are
answered at once, so a hung plotter shows within the stall timeout. Between checkpoints
the executed count is conservative: ``ESC.B`` gives it exactly at each query; the other
modes assume a full buffer and the bytes on the wire are still to execute.  After a
stroke that takes the plotter longer to draw than the link takes to carry it (by the
estimate: the link has time to spare), the sender also writes an *inline marker* ``OE;``
and goes on sending: its answer, read when it comes, says the stroke is executed and
error-free, so an error is placed within one stroke, the executed count is exact there,
and the checkpoint window moves on without draining the buffer; and the sender keeps no
more than :data:`LEAD` seconds of work in the plotter beyond the stroke it draws, so a
stop leaves little to finish.  Nor does it let the plotter hold a step that leaves the
pen where an earlier step it may still hold left it (same position, up or down), where
acknowledgements can wait for that: if the host dies, the pen's position
(:func:`locate_pen`) then tells exactly how far the plotter got.  With ``escb`` the
answers of markers and of ``ESC.B`` are both bare numbers that could cross, so ``ESC.B``
is asked only while no marker is unanswered; meanwhile the markers' answers tell the
free space (everything written before an answered marker has left the buffer), and a
plotter silent for the stall timeout is asked ``ESC.A`` (answered at once, in text) to
tell a hung plotter from a slow one.  A question left unanswered (a hang, a stop, a
garbled ``ESC.B``) may be answered late, so the next one first asks ``OI`` (a text
answer, unlike the numbers) and drops the numbers before it.

GRBL 1.1 (:class:`_GrblSender`): the ``Grbl 1.1`` banner is awaited; without one after
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

Stopping (the ``cancel`` event, KeyboardInterrupt, a serial fault, a plotter error or a
stall) stops sending, lifts the tool (HP-GL: the command being sent is finished, or
after a plotter error ``ESC.K`` discards what the plotter holds, then ``PU;`` and a
checkpoint; GRBL: feed hold ``!``, soft reset 0x18, ``$X`` if the reset left an alarm,
then the program's own preamble, which lifts the tool) and raises :class:`StreamStopped`
with the executed byte count a resume can start from.

The host waits by blocking reads with a short timeout (:data:`POLL`) or by sleeping
on the cancel event: it never spins.
"""

from __future__ import annotations

import bisect
import errno
import re
import threading
import time
from collections import deque
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable

from foldfab.errors import FoldfabError

if TYPE_CHECKING:
    from foldfab.devices import DeviceProfile
    from foldfab.plotting.progress import JobProgress, ProgressEvent
    from foldfab.programs.program import Program

POLL = 0.05
"""Seconds a blocking read waits before the sender looks at the cancel event again."""
XON, XOFF = 0x11, 0x13
GRBL_RX_BUFFER = 127
"""Bytes GRBL 1.1 may hold unacknowledged (its 128-byte receive buffer keeps one free)."""
PLANNER_BLOCKS = 16
"""GRBL's planner holds 15 motion blocks besides the one executing: lines acknowledged
after the 16th-last motion line may not have moved the machine yet."""
STATUS_INTERVAL = 0.2
"""At most 5 status queries a second."""
CHECK_EVERY = 512
"""HP-GL: bytes between checkpoints (at most one buffer): without inline markers an
HP-GL error is found within this many bytes, and a resume after it draws these bytes'
strokes again."""
VERIFY_EVERY = 4 * CHECK_EVERY
"""HP-GL: bytes between position checks (``OA`` with a checkpoint's or an inline marker's
``OE``) besides those at pauses and at the end: at a checkpoint the answer's round trip costs
link time (about 2% of the line rate if asked at every one)."""
LEAD = 1.0
"""HP-GL with inline markers: seconds of work (by the estimate) the sender lets the plotter
hold beyond the stroke it is drawing.  Markers tell the moment each stroke is done, so a
second keeps it busy, and a stop (Ctrl-C, a host that dies) leaves little in its buffer."""
GRBL_POSITION_TOLERANCE = 0.02
"""mm a GRBL status position may differ from the program's: a step (80 steps/mm) and the
report's rounding."""
BANNER_WAIT = 2.5
"""Seconds to wait for the GRBL banner (an Arduino boots in about 2 s), before and after
the soft reset."""

HPGL_ERRORS = {
    1: "instruction not recognized",
    2: "wrong number of parameters",
    3: "out-of-range parameters",
    4: "illegal character",
    5: "unknown character set",
    6: "position overflow",
    7: "buffer overflow",
}
"""``OE`` answers, as HP and Graphtec document them."""

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

Operator = Callable[[str], bool]
"""Shows a pause message; returns True to continue, False to stop the job."""


class StreamStopped(FoldfabError):
    """The job stopped before its end; the tool was lifted if the plotter could be reached."""

    def __init__(self, message: str, *, acknowledged: int, pauses_done: int, cancelled: bool,
                 lifted: bool, plotter_error: bool = False):
        super().__init__(message)
        self.acknowledged = acknowledged
        """Program bytes certainly executed: a resume starts at the first stroke after them."""
        self.plotter_error = plotter_error
        """The plotter reported an error: it skipped an instruction, so where its pen stopped
        does not tell how far it drew correctly (a resume must not be located by it)."""
        self.pauses_done = pauses_done
        self.cancelled = cancelled
        """Stopped on request (cancel event, Ctrl-C, no at a pause), not by a fault."""
        self.lifted = lifted
        self.exit_code = 130 if cancelled else 2


@dataclass(frozen=True)
class StreamResult:
    """A finished job."""

    sent: int
    elapsed: float
    waited: float
    """Seconds spent waiting for the operator."""
    pauses: int


class _Cancelled(Exception):
    """The job was stopped on request."""


class _Fault(Exception):
    """The plotter or the link failed.  ``suspect``: a plotter error somewhere since the
    last checkpoint, so those bytes count as not executed."""

    def __init__(self, message: str, suspect: bool = False):
        super().__init__(message)
        self.suspect = suspect


def stream(port, program: Program, device: DeviceProfile, *,
           events: Callable[[ProgressEvent], None] | None = None,
           cancel: threading.Event | None = None, operator: Operator | None = None,
           stall_timeout: float = 30.0, progress: JobProgress | None = None,
           note: str = "") -> StreamResult:
    """Send ``program`` to the plotter on ``port`` (open, with the profile's settings).

    ``events`` receives :class:`~foldfab.plotting.progress.ProgressEvent` objects; setting
    ``cancel`` (or a KeyboardInterrupt) stops the job safely; ``operator`` answers the
    program's pauses (without one, a pause stops the job).  ``stall_timeout``: seconds
    without a sign of progress, beyond the time the estimate expects the plotter to
    need, before the job is stopped as stalled.  Raises :class:`StreamStopped` if the
    job did not finish.
    """
    if program.protocol != device.protocol:
        raise FoldfabError(f"a {program.protocol} program cannot run on {device.name} ({device.protocol})")
    sender = _GrblSender if device.protocol == "gcode" else _HPGLSender
    return sender(port, program, device, events, cancel, operator, stall_timeout, progress).run(note)


@dataclass(frozen=True)
class PenPosition:
    """Where a plotter's pen is, in device units (HP-GL plotter units, G-code mm), and
    whether it is down."""

    x: float
    y: float
    down: bool


def locate_pen(port, device: DeviceProfile, timeout: float = 10.0) -> PenPosition | None:
    """Ask a plotter where its pen stopped after a job lost its host; None if it cannot know.

    HP-GL: ``ESC.K`` (abort graphics), sent twice, first discards what the plotter still
    holds from the lost connection, including an instruction a pulled cable cut in two,
    which would otherwise run together with the next one; ``OI`` waits for the move in
    progress and skips answers meant for the lost host; ``OS`` says whether the plotter
    was initialized since (switched off and on, or another program's ``IN``: its position
    then says nothing about the job; the engine reads ``OS`` at its first checkpoint,
    which clears the job's own ``IN``); ``OA`` gives the pen.

    GRBL: a board that greets on opening has just rebooted (an Arduino's DTR reset) and
    lost its position: None.  Otherwise, once the status says ``Idle`` (the lines it held
    are done), a soft reset clears a line the cable cut in two (GRBL keeps its position
    when reset at rest) and the status report gives the position; a Z tool stays where it
    was, a servo pen's state is lost with the reset (None).
    """
    from foldfab.programs.program import Program

    empty = Program("", device.protocol, device.name, (), ())
    sender = _GrblSender if device.protocol == "gcode" else _HPGLSender
    return sender(port, empty, device, None, None, None, timeout, None).locate()


def char_time(port) -> float:
    """Seconds one byte takes on the wire at the port's settings."""
    bits = 1 + port.bytesize + (0 if port.parity == "N" else 1) + float(port.stopbits)
    return bits / float(port.baudrate)


def plotter_clock(port) -> Callable[[], float]:
    """The clock the plotter on ``port`` runs on, in seconds: a simulator's virtual clock
    (``sim://`` at ``time=fast`` or ``instant`` runs faster than the wall clock), else the
    wall clock.  A job's elapsed time, its waits and so its ETA are all read on it, so the ETA
    is in the same seconds as the estimate it scales and as the time the job then takes; a
    rehearsal on a fast simulator tells how long the real plotter will take."""
    simulator = getattr(port, "simulator", None)
    return simulator.clock.now if simulator is not None else time.monotonic


class _Sender:
    """What both protocols share: events, timing, replies, stopping."""

    def __init__(self, port, program, device, events, cancel, operator, stall_timeout, progress):
        from foldfab.plotting.progress import JobProgress

        self.port, self.program, self.device = port, program, device
        self.data = program.encode()
        self.events = events or (lambda event: None)
        self.cancel = cancel or threading.Event()
        self.operator = operator
        self.stall_timeout = stall_timeout
        self.progress = progress or JobProgress(program, device)
        self.sent = 0
        """Program bytes written."""
        self.acked = 0
        """Program bytes certainly executed."""
        self.reported = 0
        """:attr:`acked` as the last progress event gave it (and a queue may have saved)."""
        self.pauses_done = 0
        self.waited = 0.0
        self.clock = plotter_clock(port)
        self.clock_started = self.clock()
        self.started = time.monotonic()
        self.last_event = 0.0
        self.alive = self.started  # the last sign of progress from the plotter
        self.char_time = char_time(port)
        self.wire_free = 0.0  # when the bytes written so far will have left the wire
        self.inbox = bytearray()
        self.stopping = False
        self.plotter_error = False  # the plotter reported an error (see StreamStopped)

    def run(self, note: str = "") -> StreamResult:
        timeout = self.port.timeout
        self.port.timeout = POLL
        try:
            try:
                self.emit("start", note)
                self.send_program()
            except KeyboardInterrupt:
                self.stop("stopped by Ctrl-C", cancelled=True)
            except _Cancelled as exc:
                self.stop(str(exc), cancelled=True)
            except _Fault as exc:
                self.stop(str(exc), suspect=exc.suspect)
            except OSError as exc:  # serial.SerialException is an OSError
                self.stop(f"serial link to {self.device.name} failed: {exc}", link_lost=True)
            self.acked = self.sent
            self.emit("done")
            return StreamResult(self.sent, self.elapsed, self.waited, self.pauses_done)
        finally:
            try:
                self.port.timeout = timeout
            except (OSError, ValueError):
                pass

    def send_program(self) -> None:
        raise NotImplementedError

    def lift(self, suspect: bool) -> str:
        """Lift the tool after a stop; returns a note for the message ("" if all went well)."""
        raise NotImplementedError

    def stop(self, reason: str, cancelled: bool = False, suspect: bool = False,
             link_lost: bool = False) -> None:
        """Stop safely, then raise StreamStopped."""
        self.stopping = True
        lifted, note = self.sent == 0, ""  # nothing sent: the tool was never lowered
        if not link_lost and not lifted:
            try:
                note = self.lift(suspect)
                lifted = True
            except KeyboardInterrupt:
                note = "lifting the tool was interrupted: lift it by hand"
            except (_Fault, _Cancelled, OSError) as exc:
                note = f"could not lift the tool ({exc}): lift it by hand"
        message = reason + (f"; {note}" if note else "")
        self.emit("stopped", message)
        raise StreamStopped(message, acknowledged=self.acked, pauses_done=self.pauses_done,
                            cancelled=cancelled, lifted=lifted,
                            plotter_error=suspect or self.plotter_error)

    # -- time and events ---------------------------------------------------------------------
    @property
    def elapsed(self) -> float:
        """Seconds of the job on the plotter's clock (see :func:`plotter_clock`)."""
        return self.clock() - self.clock_started

    def emit(self, kind: str, message: str = "") -> None:
        self.last_event = time.monotonic()
        self.events(self.progress.event(kind, self.acked, self.sent, self.elapsed, self.waited, message))
        self.reported = self.acked

    def tick(self) -> None:
        """A progress event, at most 10 a second."""
        if time.monotonic() - self.last_event >= 0.1:
            self.emit("progress")

    def patience(self, start: int, end: int) -> float:
        """Seconds to wait for the plotter to execute program bytes ``start..end``
        (twice the estimate, plus the stall timeout) before calling it stalled."""
        done = self.progress.time_done
        first = self.progress.strokes_done(start)
        last = min(self.progress.strokes_done(end) + 1, len(done) - 1)
        return self.stall_timeout + 2.0 * max(done[last] - done[min(first, last)], 0.0)

    def stalled(self, limit: float) -> bool:
        return time.monotonic() - self.alive > limit

    def misplaced(self, actual: tuple, expected: tuple, unit: str, offset: int) -> _Fault:
        """The fault of a position check that disagreed: the plotter drew something other
        than the program since the last check that agreed."""
        where = lambda p: ",".join(f"{v:g}" for v in p[:-1]) + (  # noqa: E731
            "" if p[-1] is None else " pen down" if p[-1] else " pen up")
        return _Fault(f"{self.device.name} is at {where(actual)}, expected {where(expected)} ({unit}) "
                      f"after program byte {offset}: line noise or lost steps (check the cable and "
                      "the baud rate); what it drew since the last check that agreed may be wrong",
                      suspect=True)

    def check_cancel(self) -> None:
        if self.cancel.is_set() and not self.stopping:
            raise _Cancelled("stopped on request")

    def ask_operator(self, message: str) -> None:
        """Show a pause message and wait for the operator's answer."""
        self.emit("pause", message)
        if self.operator is None:
            raise _Fault(f"stopped at a pause: nobody to answer it ({message})")
        start = self.clock()
        go = self.operator(message)
        self.waited += self.clock() - start
        self.alive = time.monotonic()
        if not go:
            raise _Cancelled("stopped at a pause by the operator")
        self.pauses_done += 1
        self.emit("resume", message)

    # -- the port ------------------------------------------------------------------------
    def write(self, data: bytes) -> None:
        """Write bytes (never an int: pyserial would send that many zero bytes)."""
        if not isinstance(data, bytes):
            raise TypeError(f"write bytes, not {type(data).__name__}")
        start = max(time.monotonic(), self.wire_free)
        self.port.write(data)
        self.wire_free = max(start + len(data) * self.char_time, time.monotonic())

    def on_wire(self) -> float:
        """Bytes written that, at the line rate, are still on their way."""
        return max(self.wire_free - time.monotonic(), 0.0) / self.char_time

    def receive(self, wait: bool) -> None:
        """Move incoming bytes to the inbox; with ``wait``, block up to POLL for the first."""
        self.check_cancel()
        waiting = self.port.in_waiting
        if waiting or wait:
            data = self.port.read(max(waiting, 1))
            if data and self.port.in_waiting:
                data += self.port.read(self.port.in_waiting)
            self.inbox += self.filter(data)

    def filter(self, data: bytes) -> bytes:
        """Handle bytes that are not replies (XON/XOFF); return the rest."""
        return data

    def lines(self) -> list[str]:
        """Complete reply lines in the inbox (CR or LF terminated, blank ones dropped)."""
        found = []
        while (match := re.search(rb"[\r\n]", self.inbox)) is not None:
            line = bytes(self.inbox[:match.start()]).decode("ascii", "replace").strip()
            del self.inbox[:match.end()]
            if line:
                found.append(line)
        return found


class _HPGLSender(_Sender):
    """HP-GL with XON/XOFF, RTS/CTS, ESC.B polling or no handshake."""

    def __init__(self, *args):
        super().__init__(*args)
        buffer = self.device.buffer
        self.flow, self.size = buffer.flow_control, buffer.size
        self.ahead = max(8, min(64, self.size // 32))
        """Bytes allowed on the wire ahead of the line rate (xonxoff, rtscts).  Twice this
        (what is on the wire, and one more write before XOFF is read) must fit in the
        headroom a plotter keeps after signalling stop (HP: 1/8 of the buffer or more)."""
        self.driver_flow = bool(self.port.xonxoff if self.flow == "xonxoff" else
                                self.port.rtscts if self.flow == "rtscts" else False)
        """The port's driver obeys the handshake (pyserial xonxoff/rtscts)."""
        self.cts_line = True  # the port can report CTS
        self.check_every = min(self.size, CHECK_EVERY)
        self.checked = 0  # program bytes executed at the last checkpoint
        self.verified = -1  # program offset of the last position check that agreed
        self.asked = -1  # program offset of the last position question (OA) written
        self.xoff = False
        self.credit = 0  # escb: bytes that fit by the last answer to ESC.B
        self.capacity = 0  # escb: the most free space ever reported (an empty buffer)
        self.replies: deque[str] = deque()
        self.unsure = False  # a question went unanswered: its answer may still come
        self.identities = 0  # OI questions not answered yet
        self.marks: deque[tuple[int, int, tuple | None]] = deque()
        """Inline markers not yet answered: (program offset, :attr:`buffered` when written,
        the expected pen position if ``OA;`` follows its ``OE;``); offset -1 once an earlier
        marker failed."""
        self.marked = self.marked_strokes()
        """Ends (program offsets) of the strokes an inline marker follows."""
        self.buffered = 0  # bytes written into the plotter's buffer (all but ESC. instructions)
        self.repeat_ends, self.repeat_before = self.repeated_states() if self.marked else ([], [])
        """Program offsets after which the pen is where a step before it left it, and that
        step's offset (see :meth:`repeats_allow`)."""
        self.repeat_index = 0  # repeats before this one are sent, or not in the way any more
        self.probes = 0  # escb: ESC.A questions (is the plotter there?) not answered yet
        self.heard = 0.0  # when the plotter last answered a marker or a probe
        self.failed_mark: int | None = None  # what a marker answered instead of 0 (None: garbled)
        self.ends = [i + 1 for i, byte in enumerate(self.data) if byte == ord(";")]
        self.check_instructions()
        from foldfab.programs.interpret import pen_states

        first_move = re.search(rb"P[UDA][-+\d][^;]*;", self.data)
        self.known_from = first_move.end() if first_move else len(self.data) + 1
        """Program offset from which the interpreter knows the pen's position."""
        self.states = pen_states(self.program.text, "hpgl", self.device)
        self.state: tuple[int, float, float, bool] | None = None  # the last step read from states

    def check_instructions(self) -> None:
        """Refuse a program with an instruction longer than the buffer can take where the
        sender needs room for whole instructions: it would wait for it forever (``escb``),
        or check the plotter in its middle (``none``).  With ``xonxoff`` and ``rtscts`` the
        plotter's handshake paces the pieces of a long one."""
        if self.flow not in ("escb", "none"):
            return
        limit = self.size - 3  # room for the instruction and an OE; marker after it
        start = 0
        for end in self.ends:
            if end - start > limit:
                raise FoldfabError(
                    f"program instruction at byte {start} is {end - start} bytes long; "
                    f"{self.device.name}'s {self.size}-byte buffer takes HP-GL instructions of at "
                    f"most {limit}: write the program again for this profile (foldfab splits long PD lists)")
            start = end

    def position_due(self) -> bool:
        """:data:`VERIFY_EVERY` bytes since the last position question."""
        return self.sent - self.asked >= VERIFY_EVERY

    def check_position(self, answer: list[int], expected: tuple[float, float, bool], offset: int) -> None:
        """Compare an ``OA`` answer (x, y, pen) with the position the program leaves after byte
        ``offset``."""
        x, y, down = answer
        if abs(x - expected[0]) > 1 or abs(y - expected[1]) > 1 or bool(down) != expected[2]:
            self.checked = max(self.verified, 0)  # a resume draws again from the last check that agreed
            self.marks = deque((-1, b, e) for _, b, e in self.marks)
            raise self.misplaced((x, y, bool(down)), expected, "plotter units", offset)
        self.verified = offset

    def expected_position(self, offset: int) -> tuple[float, float, bool] | None:
        """Where the program leaves the pen after byte ``offset`` (plotter units, down), by
        the interpreter; None before its first absolute move (the pen is where the last job
        left it).  Offsets must not decrease from one call to the next."""
        if offset < self.known_from:
            return None
        while self.state is None or self.state[0] < offset:
            end, machine = next(self.states, (len(self.data), None))
            if machine is None:
                break
            self.state = (end, machine.position[0], machine.position[1], machine.stroke is not None)
        return self.state[1:] if self.state is not None and self.state[0] == offset else None

    def send_program(self) -> None:
        pauses = sorted(self.program.pauses, key=lambda p: p.offset)
        # the setup, then a checkpoint: its OS clears the "initialized" that IN set (see locate_pen)
        self.send_until(min([*self.progress.starts[:1], *(p.offset for p in pauses), len(self.data)]))
        self.checkpoint()
        for mark in pauses:
            self.send_until(mark.offset)
            self.checkpoint(final=True)
            self.ask_operator(mark.message)
        self.send_until(len(self.data))
        self.checkpoint(final=True)

    # -- sending --------------------------------------------------------------------------
    def command_end(self, offset: int, limit: int) -> int:
        """End of the command containing byte ``offset`` (at most ``limit``)."""
        index = bisect.bisect_right(self.ends, offset)
        return min(self.ends[index], limit) if index < len(self.ends) else limit

    def send_until(self, stop: int) -> None:
        """Send whole commands up to byte ``stop`` as the handshake allows."""
        while self.sent < stop:
            self.check_cancel()
            if self.sent - self.checked >= self.check_every:
                self.await_marks()
            if self.sent - self.checked >= self.check_every:
                self.checkpoint()
            if self.marks and self.queued() > LEAD:
                self.await_marks(lambda: self.queued() <= LEAD)
            command = self.command_end(self.sent, stop) - self.sent
            if self.flow == "escb":  # several commands per ESC.B question
                need = min(max(command, self.size // 8), self.size - 3, stop - self.sent)
            else:
                need = min(command, self.ahead if self.flow != "none" else self.size - 3)
            room = min(self.room(need), self.checked + self.check_every - self.sent)
            stroke = bisect.bisect_right(self.progress.ends, self.sent)
            if stroke < len(self.progress.ends) and self.progress.ends[stroke] in self.marked:
                room = min(room, self.progress.ends[stroke] - self.sent)  # its marker follows at once
            if self.marks:  # progress comes stroke by stroke: keep the pen states in flight unique
                allowed = self.repeats_allow()
                if allowed <= self.sent:
                    self.await_marks(lambda: self.repeats_allow() > self.sent)
                    continue
                room = min(room, allowed - self.sent)
            # as many whole commands as fit; a command longer than the room goes in pieces
            index = bisect.bisect_right(self.ends, min(self.sent + room, stop)) - 1
            end = self.ends[index] if index >= 0 and self.ends[index] > self.sent else self.sent + room
            end = min(end, stop)
            while True:
                self.write(self.data[self.sent:end])
                self.credit -= end - self.sent
                self.sent = end
                if self.data[end - 1] == ord(";") or end == stop:
                    break  # a command is never left half sent (a stop appends PU;)
                rest = self.command_end(self.sent, stop) - self.sent
                end = self.sent + min(self.room(rest), rest)
            if self.sent in self.marked:  # a position check may ride on it when due (no drain)
                expected = self.expected_position(self.sent) if self.position_due() else None
                marker = b"OE;OA;" if expected is not None else b"OE;"
                self.asked = self.sent if expected is not None else self.asked
                self.room(len(marker))
                self.write(marker)
                self.credit -= len(marker)
                self.marks.append((self.sent, self.buffered, expected))
            self.update_acked()
            self.tick()

    def room(self, need: int) -> int:
        """Block until at least ``need`` bytes may be sent; return how many may."""
        if self.flow == "escb":
            return self.escb_room(need)
        if self.flow == "none":  # one buffer between checkpoints (markers are in it too)
            free = lambda: (self.checked + self.size - 3 - self.sent  # noqa: E731
                            - sum(3 if expected is None else 6 for _, _, expected in self.marks))
            self.receive(wait=False)
            self.absorb_marks()
            if free() < need:
                self.await_marks(lambda: free() >= need)
            if free() < need:
                self.checkpoint()
            return free()
        want = max(min(need, self.ahead), self.ahead // 2)  # no dribbling a byte at a time
        self.alive = time.monotonic()
        while True:
            if not self.driver_flow or self.marks:  # else the port's driver holds writes and eats XON/XOFF
                self.receive(wait=False)
            self.absorb_marks()
            held = self.xoff if self.flow == "xonxoff" else not self.clear_to_send()
            if not held:
                on_wire = self.on_wire()
                if on_wire <= self.ahead - want:
                    return int(self.ahead - on_wire)
                self.sleep((on_wire - (self.ahead - want)) * self.char_time)
                continue
            limit = self.patience(self.acked, self.sent + self.ahead)
            if self.stalled(limit):
                signal = "no XON" if self.flow == "xonxoff" else "CTS low"
                raise _Fault(f"{self.device.name} stalled: {signal} for {limit:.0f} s "
                             "(paper jam, pause button, or the plotter hung?)")
            self.receive(wait=True)  # a poll interval: XON comes as a byte, CTS is polled

    def clear_to_send(self) -> bool:
        """CTS; a port without modem lines (a pseudo-terminal) leaves it to the driver."""
        if not self.cts_line:
            return True
        try:
            return self.port.cts
        except OSError as exc:
            if exc.errno not in (errno.ENOTTY, errno.EINVAL):
                raise
            if not self.driver_flow:
                raise _Fault(f"{self.port.port} has no CTS line to read: open it with RTS/CTS "
                             "flow control (--rtscts) so that its driver holds the data") from None
            self.cts_line = False
            return True

    def sleep(self, seconds: float) -> None:
        """Sleep on the cancel event (wakes at once on a cancel)."""
        self.check_cancel()
        if seconds > 0 and not self.stopping:
            self.cancel.wait(min(seconds, POLL))
        elif seconds > 0:
            time.sleep(min(seconds, POLL))

    def escb_room(self, need: int) -> int:
        """Ask ``ESC.B`` until the plotter reports at least ``need`` bytes free."""
        best, since = -1, time.monotonic()
        while self.credit < need:
            if self.marks:  # their answers free the space; an ESC.B answer now could pass for one
                self.await_marks(lambda: self.credit >= need)
                continue
            self.credit = self.ask(b"\x1b.B", "ESC.B (free buffer space)", self.stall_timeout)[0]
            self.capacity = max(self.capacity, self.credit)
            self.acked = max(self.acked, self.sent - (self.capacity - self.credit))
            if self.credit >= need:
                break
            if self.credit > best:
                best, since = self.credit, time.monotonic()
            limit = self.patience(self.acked, self.sent)
            if time.monotonic() - since > limit:
                raise _Fault(f"{self.device.name} stalled: its buffer has not drained for "
                             f"{limit:.0f} s (paper jam, pause button, or the plotter hung?)")
            self.tick()
            self.receive(wait=True)  # a poll interval; replies do not come unasked
        return self.credit

    def update_acked(self) -> None:
        """Executed bytes as far as known without asking (see the module docstring)."""
        if self.flow in ("xonxoff", "rtscts"):
            self.acked = max(self.acked, self.sent - self.size - self.ahead)
        self.acked = max(self.acked, self.checked)

    def marked_strokes(self) -> frozenset[int]:
        """Ends of the strokes the plotter takes longer to draw than the link to carry (with
        their marker): the link has time to spare for one."""
        ends, done = self.progress.ends, self.progress.time_done
        starts = [0, *ends[:-1]]
        return frozenset(end for k, (start, end) in enumerate(zip(starts, ends))
                         if done[k + 1] - done[k] > (end - start + 3) * self.char_time)

    def repeated_states(self) -> tuple[list[int], list[int]]:
        """The steps of the program that leave the pen (position, up or down) where an earlier
        step left it: their end offsets, and the end offset of that earlier step."""
        from foldfab.programs.interpret import pen_states

        last: dict[tuple[int, int, bool], int] = {}
        ends, before = [], []
        for end, machine in pen_states(self.program.text, "hpgl", self.device):
            key = (round(machine.position[0]), round(machine.position[1]), machine.stroke is not None)
            if key in last:
                ends.append(end)
                before.append(last[key])
            last[key] = end
        return ends, before

    def repeats_allow(self) -> int:
        """How far the sender may go before the next step whose pen state repeats one the
        pen locator's window may still hold (from the end of the last acknowledged stroke,
        see :func:`foldfab.plotting.resume.first_undrawn`).  A repeat that only acknowledging strokes
        not yet sent could clear (within a stroke of the earlier one) is let through: there
        the locator takes the earlier state, never a later one."""
        ends = self.progress.ends
        start = lambda done: ends[done - 1] if done >= 1 else 0  # noqa: E731
        window = start(self.progress.strokes_done(self.reported))  # where a resume would look from
        reachable = start(self.progress.strokes_done(self.sent))
        k = self.repeat_index  # sent, or their twin out of the window: never in the way again
        while k < len(self.repeat_ends) and (self.repeat_ends[k] <= self.sent or self.repeat_before[k] < window):
            k += 1
        self.repeat_index = k
        horizon = self.sent + self.check_every  # the sender never gets further ahead than this
        while k < len(self.repeat_ends) and self.repeat_ends[k] <= horizon:
            if self.repeat_before[k] >= window and self.repeat_before[k] < reachable:
                command = bisect.bisect_left(self.ends, self.repeat_ends[k])  # the command holding it
                return self.ends[command - 1] if command > 0 else 0
            k += 1
        return len(self.data)

    def queued(self) -> float:
        """Estimated seconds of the strokes sent after the one the plotter is drawing."""
        done, progress = self.progress.time_done, self.progress
        last = progress.strokes_done(self.sent)
        return done[last] - done[min(progress.strokes_done(self.checked) + 1, last)]

    def await_marks(self, enough: Callable[[], bool] | None = None) -> None:
        """Read marker answers until ``enough()`` (default: the checkpoint window has room
        again) or none is left to come; a plotter that stops answering is stalled."""
        enough = enough or (lambda: self.sent - self.checked < self.check_every)
        self.alive = self.heard = time.monotonic()
        while self.marks and not enough():
            limit = self.patience(self.checked, self.sent)
            if self.stalled(limit):
                raise self.unanswered("OE (output error)", limit)
            if self.flow == "escb":  # keep ESC.B's promptness: a hung plotter shows within the stall timeout
                silent = time.monotonic() - self.heard
                if self.probes and silent > self.stall_timeout + self.on_wire() * self.char_time:
                    raise self.unanswered("ESC.A (identification)", self.stall_timeout)
                if not self.probes and silent > self.stall_timeout:
                    self.write(b"\x1b.A")  # answered at once, in text: never taken for a marker's number
                    self.probes += 1
                    self.heard = time.monotonic()
            self.receive(wait=True)
            self.absorb_marks()
            self.tick()

    # -- replies ---------------------------------------------------------------------------
    def absorb_marks(self) -> None:
        """Take the answers of inline markers that have come: each says the bytes up to its
        marker are executed; one that is not 0 is an HP-GL error since the marker before."""
        self.replies.extend(self.lines())
        while self.probes and any(not _NUMBERS.fullmatch(line) for line in self.replies):
            self.replies.remove(next(line for line in self.replies if not _NUMBERS.fullmatch(line)))
            self.probes -= 1
            self.heard = time.monotonic()
        while self.marks and len(self.replies) >= (1 if self.marks[0][2] is None else 2):
            self.heard = time.monotonic()
            line, (offset, buffered, expected) = self.replies.popleft(), self.marks.popleft()
            position = self.replies.popleft() if expected is not None else ""
            error = int(line) if re.fullmatch(r"\d+", line) else None
            if offset < 0:  # after a failed marker: nothing later counts as executed
                continue
            if error == 0 and expected is not None and not self.stopping:  # garbled: the pairing is lost
                self.check_position(self.numbers(position, "OA (actual pen position)", 3, suspect=True),
                                    expected, offset)
            if error == 0:
                self.acked = max(self.acked, offset)
                self.checked = max(self.checked, offset)
                self.credit = max(self.credit, self.capacity - (self.buffered - buffered))
                self.alive = time.monotonic()
                if not self.stopping:  # a stroke is done: tell at once (the queue saves it)
                    self.emit("progress")
                continue
            self.marks = deque((-1, b, e) for _, b, e in self.marks)
            self.plotter_error, self.failed_mark = True, error
            if self.stopping:  # already stopping: lift() counts the bytes since the last good marker as not done
                continue
            if error is None:
                raise _Fault(f"{self.device.name} answered OE (output error) with {line!r}, not a number "
                             "(line noise, or other serial settings?)", suspect=True)
            meaning = HPGL_ERRORS.get(error, "unknown error")
            raise _Fault(f"{self.device.name} reports HP-GL error {error} ({meaning}) in program bytes "
                         f"{self.checked}..{offset} (line noise, or a command it does not take?)",
                         suspect=True)

    def write(self, data: bytes) -> None:
        super().write(data)
        if not data.startswith(b"\x1b"):  # device-control instructions are never buffered
            self.buffered += len(data)

    def filter(self, data: bytes) -> bytes:
        if XON in data or XOFF in data:
            for byte in data:
                if byte in (XON, XOFF):
                    self.xoff = byte == XOFF
                    self.alive = time.monotonic()
            data = data.replace(bytes([XON]), b"").replace(bytes([XOFF]), b"")
        return data

    def ask(self, command: bytes, what: str, timeout: float, count: int = 1) -> list[int]:
        """Send an output instruction; return the first ``count`` integers of its answer."""
        return self.ask_all([(command, what, count)], timeout)[0]

    def ask_all(self, questions: list[tuple[bytes, str, int]], timeout: float) -> list[list[int]]:
        """Send output instructions in one write (one round trip); per (command, what,
        count): the first ``count`` integers of its answer."""
        if self.unsure:
            self.resync(timeout)
        self.write(b"".join(command for command, _, _ in questions))
        self.unsure = True  # until its answers are read: a stop may abandon the questions
        lines = [self.answer(command, what, timeout) for command, what, _ in questions]
        self.unsure = False
        return [self.numbers(line, what, count) for line, (_, what, count) in zip(lines, questions)]

    def numbers(self, line: str, what: str, count: int, suspect: bool = False) -> list[int]:
        """The first ``count`` integers of the answer ``line`` to ``what``, else a fault."""
        numbers = [n.strip() for n in line.split(",")][:count]
        if len(numbers) < count or not all(re.fullmatch(r"-?\d+", n) for n in numbers):
            raise _Fault(f"{self.device.name} answered {what} with {line!r}, not "
                         f"{'a number' if count == 1 else f'{count} numbers'} "
                         "(line noise, or other serial settings?)", suspect)
        return [int(n) for n in numbers]

    def answer(self, command: bytes, what: str, timeout: float) -> str:
        """The next reply line; a question without one makes the replies unsure."""
        deadline = time.monotonic() + timeout + self.on_wire() * self.char_time
        while not self.replies or self.marks:  # the answers of inline markers come first
            self.absorb_marks()
            if self.replies and not self.marks:
                break
            if time.monotonic() > deadline:  # its answer may still come: the replies stay unsure
                if command.startswith(b"\x1b"):  # noise may have made it a device-control
                    self.write(b":")  # instruction that takes parameters: ":" ends it
                raise self.unanswered(what, timeout)
            self.receive(wait=True)
        return self.replies.popleft()

    def unanswered(self, what: str, seconds: float) -> _Fault:
        """The fault of a question the plotter left unanswered for ``seconds``."""
        return _Fault(f"{self.device.name} did not answer {what} within {seconds:.0f} s "
                      "(switched off, hung, line noise, a loose cable, or other serial settings?)")

    def resync(self, timeout: float) -> None:
        """Ask ``OI`` (identification: text, where every other answer is a number) and drop
        the late numbers before its answers."""
        self.write(b"OI;")
        self.identities += 1
        while self.identities:
            if not _NUMBERS.fullmatch(self.answer(b"OI;", "OI (identification)", timeout)):
                self.identities -= 1
        self.unsure = False

    def locate(self) -> PenPosition | None:
        """See :func:`locate_pen`."""
        timeout = self.port.timeout
        self.port.timeout = POLL
        try:
            # twice: the lost host may have been cut off inside an ESC. sequence, which then
            # swallows the first ESC (the stray ".K" is discarded by the second ESC.K)
            self.write(b"\x1b.K\x1b.K")
            self.unsure = True  # the lost host's questions may still be answered
            status = self.ask(b"OS;", "OS (status)", self.stall_timeout)[0]
            if status & 8:
                return None
            x, y, down = self.ask(b"OA;", "OA (actual pen position)", self.stall_timeout, count=3)
            return PenPosition(x, y, bool(down))
        except _Fault as exc:
            raise FoldfabError(str(exc)) from None
        finally:
            self.port.timeout = timeout

    def checkpoint(self, final: bool = False) -> None:
        """Wait until the plotter has executed everything sent and check its error register,
        and its position at a pause, at the end (``final``) and every :data:`VERIFY_EVERY` bytes."""
        if self.sent == self.checked and self.sent and (not final or self.sent == self.verified):
            return
        if self.flow == "escb":  # drain by ESC.B: answered at once, so a hung plotter shows
            self.escb_room(self.capacity)
        elif self.flow != "none":
            self.room(3)
        if not self.checked:  # the first checkpoint: reading OS clears "initialized" (see locate_pen)
            self.ask(b"OS;", "OS (status)", self.patience(self.checked, self.sent))
        verify = final or self.position_due()
        expected = self.expected_position(self.sent) if verify else None
        self.asked = self.sent if verify else self.asked
        questions = [(b"OE;", "OE (output error)", 1)]
        if expected is not None:  # the same round trip tells where the pen is
            questions.append((b"OA;", "OA (actual pen position)", 3))
        (error,), *position = self.ask_all(questions, self.patience(self.checked, self.sent))
        self.credit = self.capacity  # the buffer is empty now
        if error:
            meaning = HPGL_ERRORS.get(error, "unknown error")
            raise _Fault(f"{self.device.name} reports HP-GL error {error} ({meaning}) in program bytes "
                         f"{self.checked}..{self.sent} (line noise, or a command it does not take?)",
                         suspect=True)
        if expected is not None:
            self.check_position(position[0], expected, self.sent)
        elif verify:
            self.verified = self.sent
        self.acked = self.checked = self.sent
        self.tick()

    def lift(self, suspect: bool) -> str:
        """Finish the command being sent (after a plotter error: abort what the plotter still
        holds instead), then ``PU;`` and a checkpoint."""
        if suspect:  # where in the window since the last checkpoint the error struck is unknown:
            self.acked = self.checked  # the resume draws it again, so the plotter need not draw it now
            self.write(b"\x1b.K\x1b.K")  # twice: noise may have left it inside an ESC. sequence
            # markers still held are discarded with the rest; answers of those already executed may
            # still come: the next question first asks OI and drops the numbers before its answer
            self.marks.clear()
            self.unsure = True
        else:
            end = self.command_end(max(self.sent - 1, 0), len(self.data))
            if 0 < self.sent < end and self.data[self.sent - 1] != ord(";"):
                self.send_until(end)
        try:
            if self.flow in ("xonxoff", "rtscts", "escb"):
                self.room(3)
        finally:  # a plotter that does not answer still gets the PU; to execute when it can
            self.write(b"PU;")
        error = self.ask(b"OE;", "OE (output error)", self.patience(self.acked, self.sent))[0]
        if error or self.plotter_error:  # since the last checkpoint or good marker: not executed
            self.acked = self.checked
            self.plotter_error = True
            code = error or self.failed_mark
            what = (f"HP-GL error {code} ({HPGL_ERRORS.get(code, 'unknown error')})" if code
                    else "a garbled OE answer")
            return "" if suspect else f"the plotter also reports {what}"
        if not suspect:
            self.acked = self.checked = self.sent
        return ""


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


_NUMBERS = re.compile(r"-?\d+(?:,-?\d+)*")
"""HP-GL answers that are numbers (OE, OS, ESC.B, OA), unlike identifications (OI, ESC.A)."""
_STATUS = re.compile(r"<([A-Za-z]+)(?::(\d+))?(.*)>")
_FIELD = re.compile(r"\|(MPos|WPos|WCO):([-\d.]+),([-\d.]+),([-\d.]+)")


class _GrblSender(_Sender):
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
        self.last_query = 0.0
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
            sync = any((letter, value) in (("G", 4), ("M", 0), ("M", 2), ("M", 3), ("M", 5), ("M", 30))
                       for letter, value in words)
            lines.append(_Line(start, end, number, data, bool(letters & {"X", "Y", "Z"}), sync))
            start = end
        return lines

    # -- replies ---------------------------------------------------------------------------
    def pump(self) -> None:
        """Ask the status when due, wait up to POLL for replies, handle them."""
        now = time.monotonic()
        if now - self.last_query >= STATUS_INTERVAL and (not self.querying or now - self.last_query > 1.0):
            self.write(b"?")
            self.last_query, self.querying, self.query_answered = now, True, self.answered
            if self.unanswered_since is None:
                self.unanswered_since = now
        elif (self.unanswered_since is not None and not self.stopping
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
        """See :func:`locate_pen`."""
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
            return PenPosition(x, y, z <= machine.down_limit)
        except _Fault as exc:
            raise FoldfabError(str(exc)) from None
        finally:
            self.port.timeout = timeout

    def send_program(self) -> None:
        self.connect()
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
