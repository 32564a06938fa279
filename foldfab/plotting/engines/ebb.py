"""The EBB engine: an EiBotBoard (AxiDraw) paced by its OK replies and its motion FIFO.

The board is asked ``V`` first and must answer with an ``EBB`` version line (as plotink's
``ebb_serial.testPort`` checks).  Then every command goes alone and the next waits for its
``OK`` (plotink's ``ebb_serial.command`` does the same): the board answers a motion command only
once its FIFO has room, so the OK replies pace the sender at motion speed.  An ``OK`` means
queued, not done: the executed count lags :data:`IN_FLIGHT` motion commands behind.  A reply
with ``Err`` stops the job (the board skipped the command).  At a pause and at the end the
sender asks ``QM`` until the command, both motors and the FIFO are idle (``QM,0,0,0,0``), so
"done" means drawn.  A stop (cancel, fault) sends ``ES`` (emergency stop: the move in progress
ends, the FIFO is emptied), raises the pen (``SP,1``) and sends the carriage home (``HM``), where
a resume (:func:`foldfab.plotting.resume.resume_program`) starts from.
"""

from __future__ import annotations

import time

from foldfab.plotting.engines.base import PenPosition, Sender, _Fault

IN_FLIGHT = 3
"""Motion commands an ``OK`` may have left unexecuted: the one running and two queued (firmware 2.x
queues one; this leaves a margin)."""
IDLE_POLL = 0.05
"""Seconds between ``QM`` questions while waiting for the motors to stop."""
HELLO_WAIT = 2.0
"""Seconds to wait for the answer to ``V``."""
MOTION = ("SM", "XM", "SP", "TP", "HM")


class EbbSender(Sender):
    """EiBotBoard: one command at a time, each answered ``OK``; ``QM`` for the end."""

    def __init__(self, *args):
        super().__init__(*args)
        from foldfab.programs.read_ebb import ebb_commands

        text = self.program.text
        self.commands = [(command.offset, end, command.name in MOTION) for command, end in ebb_commands(text)]
        self.moves_done: list[int] = []  # end offsets of the motion commands answered OK

    def send_program(self) -> None:
        self.hello()
        pauses = sorted(self.program.pauses, key=lambda p: p.offset)
        for start, end, motion in self.commands:
            while pauses and pauses[0].offset <= start:
                self.wait_idle(start)
                self.ask_operator(pauses.pop(0).message)
            self.command(self.data[start:end].rstrip(b"\r\n") + b"\r", end)
            if motion:
                self.moves_done.append(end)
                if len(self.moves_done) > IN_FLIGHT:
                    self.acked = max(self.acked, self.moves_done[-IN_FLIGHT - 1])
            self.tick()
        self.wait_idle(len(self.data))
        for mark in pauses:  # pauses at the very end
            self.ask_operator(mark.message)

    # -- the conversation ------------------------------------------------------------------
    def hello(self) -> None:
        """``V``: the board must say it is an EBB."""
        self.write(b"V\r")
        reply = self.reply(HELLO_WAIT, "its version (V)")
        if not reply.startswith("EBB"):
            raise _Fault(f"{self.device.name} answered {reply[:60]!r} to V, not an EBB version: is this "
                         "the AxiDraw's port?")

    def command(self, data: bytes, end: int) -> None:
        """Send one command and wait for its OK (a motion command: until the FIFO takes it)."""
        self.write(data)
        self.sent = max(self.sent, end)
        limit = self.patience(self.acked, end)
        reply = self.reply(limit, data.decode("ascii", "replace").strip())
        if reply != "OK":
            self.plotter_error = "Err" in reply
            raise _Fault(f"{self.device.name} answered {reply[:80]!r} to "
                         f"{data.decode('ascii', 'replace').strip()!r} (program byte {end - len(data)})",
                         suspect=self.plotter_error)

    def reply(self, limit: float, what: str) -> str:
        """The next reply line, waiting up to ``limit`` seconds of silence."""
        self.alive = time.monotonic()
        while True:
            found = self.lines()
            if found:
                self.inbox[:0] = "".join(line + "\r\n" for line in found[1:]).encode("ascii")
                self.alive = time.monotonic()
                return found[0]
            if self.stalled(limit):
                raise _Fault(f"{self.device.name} did not answer {what} within {limit:.0f} s: check the "
                             "cable and that the board is powered")
            self.receive(wait=True)

    def ask(self, query: bytes, data_lines: int) -> list[str]:
        """A query's data lines (and its OK, when it sends one)."""
        self.write(query)
        answers = [self.reply(self.stall_timeout, query.decode().strip()) for _ in range(data_lines)]
        if query.startswith((b"QP", b"QS", b"ES")):
            self.reply(self.stall_timeout, query.decode().strip())
        return answers

    def wait_idle(self, offset: int) -> None:
        """Ask ``QM`` until nothing executes, no motor moves and the FIFO is empty."""
        patience = self.patience(self.acked, offset)
        deadline = time.monotonic() + patience
        while True:
            answer = self.ask(b"QM\r", 1)[0]
            fields = answer.split(",")
            if fields[0] != "QM" or not all(f.strip() in ("0", "1") for f in fields[1:]) or len(fields) < 4:
                raise _Fault(f"{self.device.name} answered {answer[:60]!r} to QM, expected QM,c,m1,m2[,f]")
            if all(f.strip() == "0" for f in fields[1:]):
                self.acked = offset
                return
            if time.monotonic() > deadline:
                raise _Fault(f"{self.device.name} still moving {patience:.0f} s after the last command")
            self.tick()
            self.cancel.wait(IDLE_POLL)
            self.check_cancel()

    def lift(self, suspect: bool) -> str:
        """Stop the motors (``ES``), raise the pen, send the carriage home (``HM``)."""
        from foldfab.programs.ebb import homing

        self.inbox.clear()
        self.port.reset_input_buffer()
        self.ask(b"ES\r", 1)
        for command in homing(self.device).split("\r")[:-1]:
            self.command(command.encode("ascii") + b"\r", self.sent)
        return ""

    def locate(self) -> PenPosition | None:
        """An EBB keeps no position a resume can trust after its host was lost (it goes on with its
        FIFO, then rests wherever that ends): the resume starts from home (``HM``)."""
        return None

