"""The HP-GL engine: send whole commands as the plotter's handshake allows, and check them.

HP-GL (:class:`HPGLSender`) sends whole commands (``;``-terminated) and never sends
past a pause:

* ``xonxoff``: foldfab reads XOFF (0x13) and XON (0x11) itself, so the handshake also
  holds where no driver does it (sockets, pseudo-terminals, ``--no-xonxoff``); writes
  are paced at the line rate so that at most :attr:`HPGLSender.ahead` bytes are on the
  wire when XOFF comes (a pseudo-terminal's kernel buffer would otherwise hold kilobytes).
  The pace is the plotter's clock, awaited in a blocking read (an XOFF or an answer ends
  it).  Where the port's driver obeys the handshake, :data:`DRIVER_LEAD` of line time is
  written ahead, so a host that runs late (a busy machine) does not leave the link idle.
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
exact there; half a window after the last acknowledged byte an inline marker (below) is
written if none is on its way, and its answer, read while the rest of the window goes out,
moves the window on, so the link does not wait for the checkpoint's round trip; with ``escb`` the buffer is first drained by ``ESC.B`` polls, which are
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
"""

from __future__ import annotations

import bisect
import errno
import re
import time
from collections import deque
from typing import Callable

from foldfab.errors import FoldfabError
from foldfab.plotting.engines.base import CHECK_EVERY, POLL, PenPosition, Sender, _Fault

XON, XOFF = 0x11, 0x13
VERIFY_EVERY = 4 * CHECK_EVERY
"""HP-GL: bytes between position checks (``OA`` with a checkpoint's or an inline marker's
``OE``) besides those at pauses and at the end: at a checkpoint the answer's round trip costs
link time (about 2% of the line rate if asked at every one)."""
LEAD = 1.0
"""HP-GL with inline markers: seconds of work (by the estimate) the sender lets the plotter
hold beyond the stroke it is drawing.  Markers tell the moment each stroke is done, so a
second keeps it busy, and a stop (Ctrl-C, a host that dies) leaves little in its buffer."""

DRIVER_LEAD = 0.5
"""HP-GL with a driver that obeys the handshake: seconds of line time the sender keeps written
ahead of the wire (at most a buffer)."""

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

_NUMBERS = re.compile(r"-?\d+(?:,-?\d+)*")
"""HP-GL answers that are numbers (OE, OS, ESC.B, OA), unlike identifications (OI, ESC.A)."""


class HPGLSender(Sender):
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
        if self.driver_flow:  # it holds the bytes when told to stop: the lead need not fit the
            # plotter's headroom, only outlast the host's own delays (a busy machine), up to a buffer
            self.ahead = max(self.ahead, min(self.size, round(DRIVER_LEAD / self.char_time)))
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
            half = self.checked + self.check_every // 2
            if not self.marks and self.sent < half:  # a window marker goes there (see window_marker)
                room = min(room, half - self.sent)
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
            if self.sent in self.marked or self.window_marker(stop):  # a position check may ride on it
                expected = self.expected_position(self.sent) if self.position_due() else None
                marker = b"OE;OA;" if expected is not None else b"OE;"
                self.asked = self.sent if expected is not None else self.asked
                self.room(len(marker))
                self.write(marker)
                self.credit -= len(marker)
                self.marks.append((self.sent, self.buffered, expected))
            self.update_acked()
            self.tick()

    def window_marker(self, stop: int) -> bool:
        """An inline marker is due half a checkpoint window after the last acknowledged byte, if
        none is on its way (see the module docstring)."""
        return (not self.marks and self.sent < stop and self.data[self.sent - 1] == ord(";")
                and self.sent - self.checked >= self.check_every // 2)

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
                self.let_pass((on_wire - (self.ahead - want)) * self.char_time)
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
        """See :func:`foldfab.plotting.stream.locate_pen`."""
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
