"""What every streaming engine shares: the base sender, how a job ends, and the link's timing.

:class:`Sender` holds what both protocols share (events, timing, replies, stopping); each
protocol's engine (:mod:`~foldfab.plotting.engines.hpgl`, :mod:`~foldfab.plotting.engines.grbl`)
subclasses it.  A job ends in a :class:`StreamResult` or raises :class:`StreamStopped`.

The host waits by blocking reads with a short timeout (:data:`POLL`) or by sleeping
on the cancel event: it never spins.
"""

from __future__ import annotations

import re
import threading
import time
from dataclasses import dataclass
from typing import Callable

from foldfab.errors import FoldfabError

POLL = 0.05
"""Seconds a blocking read waits before the sender looks at the cancel event again."""
CHECK_EVERY = 512
"""HP-GL: bytes between checkpoints (at most one buffer): without inline markers an
HP-GL error is found within this many bytes, and a resume after it draws these bytes'
strokes again."""

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


@dataclass(frozen=True)
class PenPosition:
    """Where a plotter's pen is, in device units (HP-GL plotter units, G-code mm), and
    whether it is down."""

    x: float
    y: float
    down: bool


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


class Sender:
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
        start = max(self.clock(), self.wire_free)
        self.port.write(data)
        self.wire_free = max(start + len(data) * self.char_time, self.clock())

    def on_wire(self) -> float:
        """Bytes written that, at the line rate, are still on their way (on the plotter's clock,
        which paces the wire: a simulator's in fast or instant time)."""
        return max(self.wire_free - self.clock(), 0.0) / self.char_time

    def let_pass(self, seconds: float) -> None:
        """Let up to ``seconds`` (at most :data:`POLL`) pass on the plotter's clock: a blocking read
        with that timeout, so a reply or a handshake byte ends it at once; no spinning."""
        self.check_cancel()
        if seconds <= 0:
            return
        self.port.timeout = min(seconds, POLL)
        try:
            self.inbox += self.filter(self.port.read(1))
        finally:
            self.port.timeout = POLL

    def receive(self, wait: bool) -> None:
        """Move incoming bytes to the inbox; with ``wait``, block up to POLL for the first."""
        self.check_cancel()
        data = self.port.read(1) if wait else b""  # returns at once if a byte is there
        waiting = self.port.in_waiting if data or not wait else 0  # one look, no polling loop
        if waiting:
            data += self.port.read(waiting)
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
