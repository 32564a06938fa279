"""The GP-GL engine: send a chunk, poll the status until the cutter is ready, send the next.

A Silhouette has no XON/XOFF, no RTS/CTS and no ``ESC.B``: over USB a write blocks while the
cutter cannot take more (the transport's back-pressure), and the open drivers (inkscape-silhouette,
robocut) send the program in chunks of at most 1 KiB, cut after a whole command, and poll
``ESC 0x05`` after each until the cutter answers ``0`` (ready: nothing left in its buffer, the
carriage at rest).  :class:`GPGLSender` does the same, with two refinements:

* a chunk ends, where it can, at the end of a stroke, and holds at most :data:`LEAD` seconds of
  work by the estimate (at least one stroke or one command), so a stop leaves little for the
  cutter to finish and a resume draws little again;
* "ready" after a chunk means everything sent is drawn: that is the executed count a resume
  starts from, exact to the chunk, and the job is done only when the cutter is ready after
  the last one.

The status is polled every :data:`~foldfab.plotting.engines.base.POLL` seconds (a blocking read
with that timeout: no spinning).  ``2`` (tray empty: no sheet, or it came out) stops the job;
a cutter that does not answer within the stall timeout, or still moves when the estimate says
it should long be done (:meth:`~foldfab.plotting.engines.base.Sender.patience`), is stalled.
Stopping sends ``M x,y`` to the point the program has reached (tool up, the carriage stays)
after what the cutter still holds, and waits for ready.  GP-GL cutters do not report their
position, so a resume starts after the last chunk the cutter finished.
"""

from __future__ import annotations

import bisect
import time

from foldfab.errors import FoldfabError
from foldfab.plotting.engines.base import POLL, Sender, _Fault

CHUNK = 1024
"""Bytes a chunk holds at most (inkscape-silhouette's ``safe_write``: Silhouette Studio sends 1 KiB
packets by default, 3 KiB at most); never more than the profile's ``[buffer] size``."""
LEAD = 1.0
"""Seconds of work (by the estimate) a chunk holds at most, beyond its first stroke."""
FINE_POLL = 0.01
"""Seconds between status polls once a chunk should be done by the estimate (for twice its
time); :data:`~foldfab.plotting.engines.base.POLL` before and after."""
READY, MOVING, TRAY_EMPTY = "0", "1", "2"
"""The answers to ``ESC 0x05``."""
ESC, ETX = 0x1B, 0x03


class GPGLSender(Sender):
    """GP-GL in chunks, paced by status polls."""

    def __init__(self, *args):
        super().__init__(*args)
        self.tray_empty = False  # the cutter said its sheet is out
        self.questions = 0  # status requests whose answer has not been read
        self.limit = min(CHUNK, self.device.buffer.size)
        escapes = [i + 2 for i, byte in enumerate(self.data) if byte == ESC]
        self.ends = sorted({i + 1 for i, byte in enumerate(self.data) if byte == ETX} | set(escapes))
        """Where commands end: a chunk never cuts one in two."""

    def send_program(self) -> None:
        self.settle(self.stall_timeout)  # a cutter without a sheet says so before anything is sent
        for mark in sorted(self.program.pauses, key=lambda p: p.offset):
            self.send_until(mark.offset)
            self.ask_operator(mark.message)
        self.send_until(len(self.data))

    def send_until(self, stop: int) -> None:
        """Send chunks up to byte ``stop``, each once the cutter is ready after the one before."""
        while self.sent < stop:
            self.check_cancel()
            end = self.chunk_end(stop)
            self.write(self.data[self.sent:end])
            done, progress = self.progress.time_done, self.progress
            expect = done[progress.strokes_done(end)] - done[progress.strokes_done(self.sent)]
            self.sent = end
            self.alive = time.monotonic()
            self.settle(self.patience(self.acked, self.sent), expect=expect)
            self.acked = self.sent
            self.emit("progress")

    def chunk_end(self, stop: int) -> int:
        """Where the next chunk ends: the last stroke end within :data:`CHUNK` bytes and
        :data:`LEAD` seconds, else the last command end that fits (at least one command)."""
        window = min(self.sent + self.limit, stop)
        ends, done = self.progress.ends, self.progress.time_done
        first = bisect.bisect_right(ends, self.sent)  # the stroke the chunk starts in
        last = bisect.bisect_right(ends, window) - 1
        while last > first and done[last + 1] - done[first + 1] > LEAD:
            last -= 1
        if first <= last < len(ends):
            return ends[last]
        index = bisect.bisect_right(self.ends, window) - 1
        end = self.ends[index] if index >= 0 and self.ends[index] > self.sent else \
            self.ends[min(bisect.bisect_right(self.ends, self.sent), len(self.ends) - 1)]
        return min(max(end, self.sent + 1), stop)

    def settle(self, limit: float, answer_within: float | None = None, expect: float = 0.0) -> str:
        """Poll the status until the cutter is ready; a fault if its tray is empty, it answers
        something else, does not answer within ``answer_within`` seconds (default: the stall
        timeout), or is still moving after ``limit`` seconds.  ``expect``: the estimated seconds
        of work it holds: polls come every :data:`FINE_POLL` from then on, so the cutter waits
        little for the next chunk."""
        start = self.clock()
        while True:
            self.check_cancel()
            state = self.status(self.stall_timeout if answer_within is None else answer_within)
            if state == READY:
                self.alive = time.monotonic()
                return state
            if state == TRAY_EMPTY:
                self.tray_empty = True
                raise _Fault(f"{self.device.name} reports its tray empty (status 2): the sheet came out or none "
                             "is loaded; load it as it was and resume")
            if state != MOVING:
                raise _Fault(f"{self.device.name} answered the status request (ESC 0x05) with {state!r}, not 0, 1 "
                             "or 2 (a loose cable, or not a GP-GL cutter?)")
            if self.stalled(limit):
                raise _Fault(f"{self.device.name} stalled: still moving {limit:.0f} s after the last sign of "
                             "progress (jammed, or paused on its panel?)")
            elapsed = self.clock() - start
            self.let_pass(FINE_POLL if 0.8 * expect <= elapsed <= 2 * expect + POLL else POLL)
            self.tick()

    def status(self, timeout: float) -> str:
        """Ask ``ESC 0x05`` and return the answer without its ETX (the answers of earlier requests
        that went unanswered in time come first: the last answer is this one's)."""
        self.write(b"\x1b\x05")
        self.questions += 1
        deadline = time.monotonic() + timeout + self.on_wire() * self.char_time
        while self.questions:
            if ETX in self.inbox:
                answer = bytes(self.inbox[:self.inbox.index(ETX)])
                del self.inbox[:self.inbox.index(ETX) + 1]
                self.questions -= 1
                continue
            if time.monotonic() > deadline:
                raise _Fault(f"{self.device.name} did not answer the status request (ESC 0x05) within "
                             f"{timeout:.0f} s (switched off, hung, or a loose cable?)")
            self.check_cancel()
            self.inbox += self.port.read_until(b"\x03")  # blocks up to POLL (the port's timeout)
        return answer.decode("ascii", "replace").strip()

    def lift(self, suspect: bool) -> str:
        """After what the cutter holds, the tool goes up where the program has brought it (an ``M``
        there), and the cutter must become ready: then everything sent is done.  A cutter whose
        sheet came out is initialised instead (``ESC 0x04``: it drops what it holds and lifts the
        tool), so that it does not go on with the rest of a chunk on the sheet loaded next."""
        from foldfab.programs.interpret import pen_states

        if self.tray_empty:
            self.write(b"\x1b\x04")
            return "what it still held was discarded (ESC 0x04)"

        x, y = self.device.park_units
        for end, machine in pen_states(self.program.text, "gpgl", self.device):
            if end > self.sent:
                break
            x, y = machine.position
        self.write(f"M{round(x)},{round(y)}\x03".encode("ascii"))
        limit = self.patience(self.acked, self.sent) + self.stall_timeout
        self.settle(limit, answer_within=limit)
        self.acked = self.sent
        return ""

    def locate(self) -> None:
        """GP-GL cutters do not report where their tool is (see :func:`foldfab.plotting.stream.locate_pen`)."""
        raise FoldfabError(f"{self.device.name} speaks GP-GL, which has no position report: a resume starts "
                           "after the last chunk it finished")
