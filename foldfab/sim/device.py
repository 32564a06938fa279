"""Simulated plotter core: the serial wire, the receive buffer, faults, motion, statistics.

Timing model
------------
* One virtual clock (:mod:`foldfab.sim.clock`) drives the device and the wire.  The
  device is event driven: between the host's actions it runs its planner up to the
  host's time (:meth:`Simulator.advance`); events are block ends and a stall's end.
* The wire carries one byte per ``(1 start + data + parity + stop bits) / baud``
  seconds (10 bits for 8N1).  :meth:`Simulator.transmit` delivers the host's bytes at
  that rate from the moment the wire is free, pausing while the host's own flow
  control (XON/XOFF, RTS/CTS) says stop; the host's ``write`` returns when its last
  byte has arrived.  A naive one-shot write therefore arrives at wire rate while the
  device drains at motion rate, and whatever finds the buffer full is lost.
* The device takes bytes out of its buffer as it executes them (HPGL: one
  instruction, or one coordinate pair, at a time, when the previous move has ended;
  GRBL: a line at a time while its planner has room); moves, pen lifts and dwells
  take the durations of :mod:`foldfab.sim.motion` (the estimate's model).  A block that
  arrives in an empty planner starts once the device has read what it can at that
  moment (GRBL's auto cycle start), so a planned block sees the moves read with it.
* Replies cross the wire the other way at the same rate, one byte after another from
  the moment the device produces them: the host can read a byte once it has arrived
  (an ``ok`` at 9600 baud comes 4 ms after GRBL sends it, a status report 40 ms).  A
  host driver that obeys XON/XOFF itself sees them at once.
* Host reads wait in virtual time until a reply byte has arrived or their timeout
  passes; ``real``/``fast`` sleep the wall clock accordingly (never spinning),
  ``instant`` does not sleep at all.

Statistics: busy = moving, lifting, dwelling; an idle interval counts as starvation
when more bytes arrived after it, as a pause when the device was parked or held, and
not at all after the end of a program or between two jobs (:meth:`Simulator.end_job`).
See :class:`~foldfab.sim.record.SimStats`.
"""

from __future__ import annotations

import bisect
import json
import math
import re
from collections import deque
from typing import TYPE_CHECKING, Callable

import numpy as np

from foldfab.sim.clock import Clock
from foldfab.sim.motion import Block, plan_start
from foldfab.sim.record import JobRecord, PauseRecord, SimStats, layer_named, stroke_dict

if TYPE_CHECKING:
    from foldfab.devices import DeviceProfile
    from foldfab.programs.machine import Interpretation, Stroke
    from foldfab.sim.options import SimOptions

XON, XOFF = 0x11, 0x13
INF = math.inf
JOB_GAP = 30.0
"""Virtual seconds of silence from the host, the device idle and not held, that end a job
(:meth:`Simulator.end_job`).  An HP-GL program's end and its operator pauses both park the
pen (``SP0``), so a pause longer than this splits a job in two."""


class Simulator:
    """A simulated plotter: the protocol classes fill in parsing and replies."""

    protocol: str
    TERMINATOR = "\r"
    RING_SLACK = 0
    """Buffer slots that can never hold data (GRBL's ring buffer keeps one free)."""
    SPECIAL: re.Pattern[bytes]
    """Bytes handled the moment they arrive, never buffered (realtime, device control)."""
    COMPLETES: re.Pattern[bytes]
    """Bytes that may complete a command: delivered one run at a time while the device waits."""

    def __init__(self, device: DeviceProfile, options: SimOptions):
        self.device, self.options = device, options
        self.clock = Clock(options.time, options.speedup)
        self.sheet = options.sheet or device.sheet
        self.frame = device.frame(self.sheet)
        self.size = options.buffer or device.buffer.size
        self.capacity = self.size - self.RING_SLACK
        self.flow = options.flow or device.buffer.flow_control
        headroom = max(1, min(self.size // 4, max(16, self.size // 8)))
        self.high = self.size - headroom  # XOFF / CTS low at this fill
        self.low = min(self.size // 2, self.high - 1)  # XON / CTS high again at or below
        self.stats = SimStats()
        self.t = 0.0  # device time, virtual seconds
        self.rx = bytearray()  # receive buffer
        self.base = 0  # stream offset of rx[0] (buffered bytes only)
        self.out = bytearray()  # replies the host has not read, arrived or still on the wire
        self.out_arrival: list[float] = []  # when each byte of ``out`` is through the wire
        self.reply_wire_free = 0.0  # when the device's next reply byte can start on the wire
        self.planner: deque[Block] = deque()
        self.block_end: float | None = None  # when the running head block ends
        self.speed2 = 0.0  # squared speed (mm²/s²) at the end of the last block started
        self.remaining: float | None = None  # of the head block, while frozen
        self.frozen: set[str] = set()  # "stall", "hold"
        self.deferred: list[Callable[[], None]] = []  # answers held back by a stall
        self.position = (0.0, 0.0)  # device units, where the last block ended
        self.stop_requested = False  # flow control: buffer above high water
        self.xoff = False  # the last XON/XOFF sent was XOFF
        self.stall_until: float | None = None
        self.stall_at = 4 * self.size if options.stall_at is None else options.stall_at
        self.stall_done = options.stall == 0
        self.disconnected = False
        self.opened = 0  # ports opened to it so far (``power_cycle`` acts at the second)
        self.unplug_at = options.disconnect_after  # None once the cable has been pulled
        self.wire_free = 0.0  # when the host's next byte can start on the wire
        self.host_flow: frozenset[str] = frozenset()  # what the host's driver obeys
        self.swallow_flow_bytes = False  # the host's driver eats XON/XOFF (port.xonxoff)
        self._rng = np.random.default_rng(options.seed) if options.noise else None
        self._idle = 0.0
        self._parked: PauseRecord | None = None  # the pause idle time is being added to
        self._job_start: float | None = None  # first job byte of the job in progress
        self._job_bytes = 0  # bytes received before it
        self._job_drawn = 0.0  # mm drawn before it
        self._overrunning = False
        self._wire_end = 0.0  # when the host's last byte so far was through the wire
        self.line = bytearray()  # the line being read, for protocols read line by line
        self.line_start = 0  # its stream offset
        serial = device.serial
        self.configure_wire(serial.baudrate, serial.bytesize, serial.parity, serial.stopbits)

    # --- host side ----------------------------------------------------------------------

    def configure_wire(self, baudrate: int, bytesize: int, parity: str, stopbits: float) -> None:
        """The host's line settings: seconds per byte on the wire."""
        bits = 1 + bytesize + (0 if parity == "N" else 1) + stopbits
        self.byte_time = bits / baudrate

    def connect(self) -> None:
        """The host opened the port (GRBL boards reset and greet)."""

    @property
    def cts(self) -> bool:
        """Clear To Send as the device drives it: low when mute or, with RTS/CTS, when nearly full."""
        return not self.options.mute and not (self.flow == "rtscts" and self.stop_requested)

    def transmit(self, data: bytes, start: float, deadline: float | None = None) -> tuple[int, float]:
        """The host sends ``data`` from virtual time ``start``: returns (bytes sent, time done).

        Each byte takes the wire for ``byte_time`` once the previous one is through and
        the host's flow control allows; sending stops early at ``deadline``, when the
        cable is pulled, or when flow control stops it and nothing will ever resume it.
        """
        noisy = self._corrupt(data)
        sent, t = 0, max(start, self.wire_free)
        while sent < len(data) and not self.disconnected:
            self.advance(t)
            if self.host_stopped():
                resumed = self.run_until(lambda: not self.host_stopped(), deadline)
                t = max(t, self.t)
                if not resumed:
                    break
                continue
            if deadline is not None and t + self.byte_time > deadline:
                break
            count = self._chunk(noisy, sent, t, deadline)
            self._arrive(data[sent:sent + count], noisy[sent:sent + count], t)
            sent += count
            t += count * self.byte_time
        if sent:
            self.wire_free = t
        return sent, t

    @property
    def arrived(self) -> int:
        """Reply bytes through the wire by device time ``t``: what the host can read."""
        return bisect.bisect_right(self.out_arrival, self.t)

    def next_arrival(self) -> float:
        """When the next reply byte still on the wire arrives (inf: none is)."""
        count = self.arrived
        return self.out_arrival[count] if count < len(self.out_arrival) else INF

    def take_output(self, size: int) -> bytes:
        """Up to ``size`` arrived reply bytes, removed from the output."""
        size = min(size, self.arrived)
        data = bytes(self.out[:size])
        del self.out[:size], self.out_arrival[:size]
        return data

    def discard_arrived(self) -> None:
        """The host flushes its input: what has arrived goes; bytes on the wire still come."""
        self.take_output(self.arrived)

    def run_until(self, done: Callable[[], bool], deadline: float | None = None) -> bool:
        """Run events until ``done()``; False at ``deadline`` or when nothing more can happen."""
        while not done():
            te = min(self.next_event(), self.next_arrival())
            if te == INF or (deadline is not None and te > deadline):
                if deadline is not None and deadline > self.t:
                    self.advance(deadline)
                return done()
            self.advance(te)
        return True

    def run_until_idle(self) -> None:
        """Let the device finish everything it holds (e.g. after the host went away)."""
        self.run_until(lambda: False)
        self.clock.sleep_until(self.t)

    @property
    def free(self) -> int:
        """Free receive-buffer bytes."""
        return self.capacity - len(self.rx)

    # --- recording ------------------------------------------------------------------------

    @property
    def strokes(self) -> list[Stroke]:
        """Pen-down strokes drawn so far, in sheet mm, with their tools."""
        return self._drawn()

    def interpretation(self) -> Interpretation:
        """What the device drew so far, as an interpreter result (for previews)."""
        raise NotImplementedError

    def to_json(self) -> str:
        """Device, options, statistics and every drawn stroke (sheet mm) as JSON text."""
        return json.dumps({
            "device": self.device.name,
            "protocol": self.device.protocol,
            "sheet_mm": list(self.sheet),
            "options": self.options.as_dict(),
            "stats": self.stats.as_dict(),
            "strokes": [stroke_dict(s) for s in self.strokes],
        }, indent=1)

    def write_json(self, path) -> None:
        from foldfab.atomic import write_text

        write_text(path, self.to_json())

    def write_svg(self, path) -> None:
        """The drawn strokes and travel as foldfab's preview SVG, each stroke in the colour of
        the layer whose tool drew it (:func:`~foldfab.sim.record.layer_named`)."""
        from dataclasses import replace

        from foldfab.atomic import write_text
        from foldfab.programs.preview import render_preview

        run = self.interpretation()
        write_text(path, render_preview(replace(run, strokes=layer_named(run.strokes, self.device)), self.device,
                                        self.sheet))

    # --- device time --------------------------------------------------------------------

    def advance(self, t: float) -> None:
        """Run the device up to virtual time ``t``."""
        while True:
            self._work()
            if self.planner and self.block_end is None and not self.frozen:
                self._start_head()
            te = self.next_event()
            if te > t:
                break
            self._spend(te)
            self._event()
        self._spend(t)

    def next_event(self) -> float:
        """Virtual time of the device's next own event (a block or a stall ends; inf: none)."""
        if self.stall_until is not None:
            return self.stall_until
        return self.block_end if self.block_end is not None else INF

    def _event(self) -> None:
        if self.stall_until is not None:
            self.stall_until = None
            self._thaw("stall")
            deferred, self.deferred = self.deferred, []
            for action in deferred:
                action()
            return
        block = self.planner.popleft()
        self.block_end = None
        self._completed(block)
        self.stats.last_activity = self.t
        if block.done:
            block.done()
        if self.planner and not self.frozen:
            self._start_head()

    def _completed(self, block: Block) -> None:
        self.position = block.end

    def _spend(self, until: float) -> None:
        dt = until - self.t
        if dt <= 0:
            return
        stats = self.stats
        if "stall" in self.frozen:
            stats.stalled_time += dt
        elif self.frozen:
            stats.paused_time += dt
        elif self.block_end is not None:
            stats.busy_time += dt
        elif stats.first_byte is not None:
            self._idle += dt
        if self.frozen or self.block_end is not None:
            self._parked = None
        self.t = until

    def _enqueue(self, block: Block) -> None:
        """Add a block to the planner (it starts in :meth:`advance` if the planner was idle)."""
        self.planner.append(block)

    def _start_head(self) -> None:
        """The head block starts now: a planned one gets its duration (:func:`plan_start`)."""
        block = self.planner[0]
        if block.planned:
            block.duration, self.speed2 = plan_start(self.planner, self.speed2)
        else:
            self.speed2 = 0.0
        self.block_end = self.t + block.duration

    def _freeze(self, reason: str) -> None:
        if not self.frozen and self.block_end is not None:
            self.remaining, self.block_end = self.block_end - self.t, None
        self.frozen.add(reason)

    def _thaw(self, reason: str) -> None:
        self.frozen.discard(reason)
        if not self.frozen and self.planner and self.block_end is None:
            if self.remaining is None:
                self._start_head()
            else:
                self.block_end, self.remaining = self.t + self.remaining, None

    def _clear_planner(self) -> None:
        self.planner.clear()
        self.block_end = self.remaining = None
        self.speed2 = 0.0

    def head(self) -> tuple[tuple[float, float], Block | None]:
        """Where the head is now (device units) and the block it is executing, if any."""
        if not self.planner:
            return self.position, None
        block = self.planner[0]
        left = self.remaining if self.block_end is None else self.block_end - self.t
        if left is None:  # not started
            done = 0.0
        else:
            done = 1.0 - left / block.duration if block.duration > 0 else 1.0
        (x0, y0), (x1, y1) = block.start, block.end
        return (x0 + (x1 - x0) * done, y0 + (y1 - y0) * done), block

    # --- arrival ------------------------------------------------------------------------

    def host_stopped(self) -> bool:
        """The host's driver holds its bytes back (XOFF received, or CTS low, as configured)."""
        return ("xonxoff" in self.host_flow and self.xoff) or \
            ("rtscts" in self.host_flow and not self.cts)

    def _chunk(self, data: bytes, i: int, t: float, deadline: float | None) -> int:
        """How many bytes from ``data[i]`` can arrive together without anything else happening."""
        if self._in_special() or self.SPECIAL.match(data, i):
            return 1
        special = self.SPECIAL.search(data, i)
        end = special.start() if special else len(data)
        if self._hungry():
            completes = self.COMPLETES.search(data, i, end)
            end = completes.end() if completes else end
        limits = [end - i]
        if self.free > 0:  # a full buffer loses the whole run at once
            limits.append(self.free)
        te = self.next_event()
        if te < INF:
            limits.append(int((te - t) / self.byte_time))
        if deadline is not None:
            limits.append(int((deadline - t) / self.byte_time))
        if self.flow in ("xonxoff", "rtscts") and not self.stop_requested:
            limits.append(self.high - len(self.rx))
        received = self.stats.bytes_received
        if self.unplug_at is not None:
            limits.append(self.unplug_at - received)
        if not self.stall_done:
            limits.append(self.stall_at - received)
        return max(1, min(limits))

    def _arrive(self, clean: bytes, data: bytes, t: float) -> None:
        """``data`` (``clean`` before noise) arrives byte by byte after ``t``."""
        first, last = t + self.byte_time, t + len(data) * self.byte_time
        self.advance(first)
        stats = self.stats
        stats.bytes_received += len(data)
        if self._rng is not None:
            stats.bytes_corrupted += int(np.count_nonzero(
                np.frombuffer(clean, np.uint8) != np.frombuffer(data, np.uint8)))
        if len(data) == 1 and (self._in_special() or self.SPECIAL.match(data)):
            self._special(data[0])
        else:
            self._note_arrival(first)
            keep = data[:max(self.free, 0)]
            lost = len(data) - len(keep)
            if keep:
                self._store(keep)
            if lost:
                stats.bytes_lost += lost
                if keep or not self._overrunning:
                    stats.overruns += 1
                    self._overrun()
            self._overrunning = lost > 0
            stats.max_fill = max(stats.max_fill, len(self.rx))
        self._spend(last)
        self._wire_end = last
        received = stats.bytes_received
        if self.unplug_at is not None and received >= self.unplug_at:
            self.disconnected, self.unplug_at = True, None
        if not self.stall_done and received >= self.stall_at:
            self.stall_done, self.stall_until = True, self.t + self.options.stall
            self._freeze("stall")
        self.advance(last)

    def _note_arrival(self, t: float) -> None:
        """Job data (not a realtime or device-control byte) arrives: classify the idle time."""
        stats = self.stats
        if stats.first_byte is None:
            stats.first_byte = t
        if self._job_start is None:  # a new job: the wait for it was no starvation
            self._job_start, self._idle = t, 0.0
        if self._idle > 0:
            kind = self._idle_kind()
            if kind == "starved":
                stats.starved_time += self._idle
                silent = t - self.byte_time - max(t - self._idle, self._wire_end)  # the wire idle too
                if silent > 1e-9:
                    stats.link_starved_time, stats.link_starvations = (stats.link_starved_time + silent,
                                                                       stats.link_starvations + 1)
            elif kind != "ended":
                stats.paused_time += self._idle
                if self._parked is None or self._parked.reason != kind:
                    self._parked = PauseRecord(t - self._idle, 0.0, kind)
                    stats.pauses.append(self._parked)
                self._parked.duration += self._idle
            self._idle = 0.0

    def end_job(self, force: bool = False) -> JobRecord | None:
        """End the job in progress if it is over, and record it: the device is idle (nothing to
        run, not held) and its program ended (GRBL ``M2``) or the host has sent nothing for
        :data:`JOB_GAP` seconds.  ``force``: end it anyway (serving stops).  The idle time that
        follows belongs to no job, so it counts as neither starvation nor a pause.  A
        ``sim://`` port never asks: all it serves is one job."""
        if self._job_start is None:
            return None
        idle = not (self.frozen or self.planner or self.rx) and self.block_end is None
        if not force and not (idle and (self._idle_kind() == "ended" or self._idle >= JOB_GAP)):
            return None
        stats, drawn = self.stats, sum(s.length for s in self.strokes)
        job = JobRecord(len(stats.jobs) + 1, self._job_start, max(stats.last_activity or self.t, self._job_start),
                        stats.bytes_received - self._job_bytes, drawn - self._job_drawn)
        stats.jobs.append(job)
        self._job_start, self._job_bytes, self._job_drawn = None, stats.bytes_received, drawn
        self._idle, self._parked = 0.0, None
        return job

    def _corrupt(self, data: bytes) -> bytes:
        """``data`` with one random bit flipped in each byte hit by the noise."""
        if self._rng is None or not data:
            return data
        rate = self.options.noise
        draws = self._rng.random(len(data))
        hit = draws < rate
        if not hit.any():
            return data
        values = np.frombuffer(data, np.uint8).copy()
        bits = np.minimum((draws[hit] / rate * 8).astype(np.uint8), 7)
        values[hit] ^= np.left_shift(np.uint8(1), bits)
        return values.tobytes()

    def _store(self, data: bytes) -> None:
        self.rx += data
        self._update_flow()

    def _free(self, upto: int) -> None:
        """The device has read the stream up to offset ``upto``."""
        count = upto - self.base
        if count > 0:
            del self.rx[:count]
            self.base = upto
            self._update_flow()

    def _update_flow(self) -> None:
        if self.flow not in ("xonxoff", "rtscts"):
            return
        fill = len(self.rx)
        if not self.stop_requested and fill >= self.high:
            self.stop_requested = True
            self._send_flow(XOFF)
        elif self.stop_requested and fill <= self.low:
            self.stop_requested = False
            self._send_flow(XON)

    def _send_flow(self, byte: int) -> None:
        if self.flow != "xonxoff" or self.options.mute or self.disconnected:
            return
        self.xoff = byte == XOFF
        if self.xoff:
            self.stats.xoff_sent += 1
        else:
            self.stats.xon_sent += 1
        if not self.swallow_flow_bytes:
            self._send(bytes([byte]))

    def _read_line(self) -> tuple[str, int, int] | None:
        """Take the next whole line out of the buffer: (its text without the terminator, its
        start offset, the offset after the terminator).  None while it is incomplete: what has
        arrived of it waits in :attr:`line`."""
        if not self.rx:
            return None
        if not self.line:
            self.line_start = self.base
        eol = self.COMPLETES.search(self.rx)
        if eol is None:
            self.line += self.rx
            self._free(self.base + len(self.rx))
            return None
        self.line += self.rx[:eol.start()]
        end = self.base + eol.end()
        self._free(end)
        raw = self.line.decode("latin-1")
        self.line.clear()
        return raw, self.line_start, end

    def reply(self, text: str) -> None:
        """Send ``text`` and the protocol's line terminator (lost when mute or unplugged)."""
        if not self.options.mute and not self.disconnected:
            self._send((text + self.TERMINATOR).encode("ascii"))

    def _send(self, data: bytes) -> None:
        """Put reply bytes on the wire to the host, each after the one before."""
        start = max(self.t, self.reply_wire_free)
        self.out_arrival.extend(start + self.byte_time * (i + 1) for i in range(len(data)))
        self.reply_wire_free = start + self.byte_time * len(data)
        self.out += data

    # --- protocol -----------------------------------------------------------------------

    def _work(self) -> None:
        """Read and execute what the buffer holds, as far as the device can now."""
        raise NotImplementedError

    def _hungry(self) -> bool:
        """The device is waiting for the next command (so its arrival time matters)."""
        raise NotImplementedError

    def _in_special(self) -> bool:
        """The next byte continues a special sequence."""
        return False

    def _special(self, byte: int) -> None:
        """A special byte arrived (acting on it waits while the device is stalled)."""
        raise NotImplementedError

    def _when_running(self, action: Callable[[], None]) -> None:
        """Do ``action`` now, or when the stall is over."""
        if "stall" in self.frozen:
            self.deferred.append(action)
        else:
            action()

    def _overrun(self) -> None:
        """Bytes were just lost (a device may flag an error)."""

    def _idle_kind(self) -> str:
        """What idling now is: "starved", "ended", or a pause reason."""
        return "starved"

    def _drawn(self) -> list[Stroke]:
        raise NotImplementedError


class CommandDevice(Simulator):
    """A device that reads one command (or coordinate pair) out of its buffer when the previous
    move has ended, so its buffer drains at motion speed (HP-GL, GP-GL).  The protocol class
    gives ``tokenizer`` (incremental, with ``committed``), ``commands`` (a deque), ``machine``
    (a timed reader, :mod:`foldfab.sim.motion`) and :meth:`_execute`."""

    def _drawn(self) -> list[Stroke]:
        return self.machine.strokes_at(self.machine.mark())

    def _store(self, data: bytes) -> None:
        super()._store(data)
        self.commands.extend(self.tokenizer.feed(data))

    def _hungry(self) -> bool:
        return not self.frozen and not self.planner

    def _work(self) -> None:
        while not self.frozen and not self.planner:
            command = self.commands.popleft() if self.commands else None
            self._free(self.commands[0].offset if self.commands else self.tokenizer.committed)
            if command is None:
                return
            self._execute(command)

    def _execute(self, command) -> None:
        """Execute one command taken out of the buffer."""
        raise NotImplementedError
