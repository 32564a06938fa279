"""A simulated plotter or cutter behind a USB link instead of a serial wire.

USB never loses a byte: a device whose endpoint buffer (:attr:`UsbLink.fifo`, a packet or
more; the firmware moves it into the command buffer as that has room) is full NAKs the host's
bulk OUT packets and the host's transfer waits (a printer-class driver's ``write`` blocks; a libusb transfer runs
into its timeout).  :class:`UsbLink` puts any foldfab simulator (:func:`foldfab.sim.create_simulator`,
whatever its protocol) behind such a link: :meth:`UsbLink.accept` takes only as many bytes
as the endpoint buffer has room for, :meth:`UsbLink.take` gives the replies it has sent.  The
link carries a byte in :data:`BYTE_TIME` (USB 1.1 full-speed bulk moves about a megabyte a
second), so the device, not the link, sets the pace.

The simulator's fault options act as on a serial line (:mod:`foldfab.sim.options`):
``disconnect_after`` pulls the cable (every call then raises :class:`Unplugged`),
``stall``/``stall_at`` freeze the device, so its buffer stays full and the host's
writes wait (busy), ``mute`` stops every answer.  A printer-class device also reports
paper out (:attr:`UsbLink.paper_out`, or ``paper_out_after`` bytes): it then takes no data.
"""

from __future__ import annotations

import math
import threading
import time
from typing import TYPE_CHECKING, Callable

from foldfab.sim.clock import IDLE_WAIT

if TYPE_CHECKING:
    from foldfab.sim.device import Simulator

BYTE_TIME = 1e-6
"""Virtual seconds the link takes per byte (about 1 MB/s: USB full-speed bulk)."""
INSTANT_EVENTS = 1000
"""``instant`` time: device events run at most per :meth:`UsbLink.run_on` call."""
WALL_STEP = 0.002
"""Longest wall-clock sleep of a wait in real and fast time."""

# IEEE 1284 status bits as the printer class's GET_PORT_STATUS gives them (linux/lp.h)
LP_PERRORP, LP_PSELECD, LP_POUTPA = 0x08, 0x10, 0x20


class Unplugged(OSError):
    """The cable was pulled: the device is gone."""


class UsbLink:
    """A simulator on the device end of a USB link (thread-safe: a lock guards it)."""

    def __init__(self, sim: Simulator, paper_out_after: int | None = None, fifo: int = 64):
        self.sim = sim
        self.fifo = bytearray()
        """Bytes the device's endpoint took that its command buffer has no room for yet."""
        self.fifo_size = fifo
        sim.configure_wire(round(10 / BYTE_TIME), 8, "N", 1)  # 10 bits a byte: BYTE_TIME each
        self.paper_out = False
        """The device is out of paper (or its tray is empty): it takes no data and says so."""
        self.paper_out_after = paper_out_after
        self.lock = threading.RLock()

    @property
    def clock(self):
        return self.sim.clock

    def check(self) -> Simulator:
        """The simulator, brought up to now; raises :class:`Unplugged` once the cable is pulled."""
        sim = self.sim
        if sim.disconnected:
            raise Unplugged(f"device disconnected (cable pulled after {sim.stats.bytes_received} bytes)")
        sim.advance(max(sim.t, sim.clock.now()))
        return sim

    def room(self) -> int:
        """Bytes the device's endpoint takes now (none while out of paper)."""
        with self.lock:
            self.check()
            self.feed()
            return 0 if self.paper_out else self.fifo_size - len(self.fifo)

    def accept(self, data: bytes) -> int:
        """The host offers ``data``: the endpoint takes what fits; returns how many it took."""
        with self.lock:
            count = min(len(data), self.room())
            self.fifo += data[:count]
            self.feed()
            return count

    def feed(self) -> bool:
        """Move endpoint bytes into the command buffer as far as it has room; False (so that it
        can stand in a wait's condition) once the cable is pulled."""
        sim = self.sim
        count = min(len(self.fifo), max(sim.free, 0))
        if sim.unplug_at is not None:  # the cable goes exactly there, even mid-transfer
            count = min(count, sim.unplug_at - sim.stats.bytes_received)
        if self.paper_out_after is not None:
            count = min(count, self.paper_out_after - sim.stats.bytes_received)
        if count > 0 and not sim.disconnected and not self.paper_out:
            sent, until = sim.transmit(bytes(self.fifo[:count]), max(sim.wire_free, sim.clock.now(), sim.t))
            del self.fifo[:sent]
            if sim.clock.rate is None:
                sim.clock.sleep_until(until)
        if self.paper_out_after is not None and sim.stats.bytes_received >= self.paper_out_after:
            self.paper_out, self.paper_out_after = True, None
        return not sim.disconnected

    def take(self, size: int) -> bytes:
        """Up to ``size`` reply bytes the device has sent."""
        with self.lock:
            return self.check().take_output(size)

    @property
    def answering(self) -> bool:
        """Replies are waiting for the host."""
        return self.sim.arrived > 0

    def status(self) -> int:
        """The IEEE 1284 status byte a printer-class device reports: selected, no error, and
        paper out when it is."""
        return LP_PSELECD | LP_PERRORP | (LP_POUTPA if self.paper_out else 0)

    def run_on(self) -> None:
        """Let the device run up to now (``instant``: through its next events, a bounded number)."""
        with self.lock:
            sim = self.check()
            self.feed()
            if sim.clock.rate is not None:
                return
            for _ in range(INSTANT_EVENTS):
                self.feed()
                upcoming = min(sim.next_event(), sim.next_arrival())
                if upcoming == math.inf:
                    break
                sim.clock.sleep_until(upcoming)
                sim.advance(upcoming)
            self.feed()

    def wait(self, ready: Callable[[], bool], timeout: float | None) -> bool:
        """Block until ``ready()`` or ``timeout`` virtual seconds have passed (None: no limit);
        in ``instant`` time the device runs ahead to the event."""
        clock = self.clock
        deadline = math.inf if timeout is None else clock.now() + timeout
        while True:
            with self.lock:
                sim = self.check()
                if ready():
                    return True
                if clock.rate is None:
                    limit = None if deadline == math.inf else deadline
                    if sim.run_until(lambda: (self.feed() and ready()) or sim.disconnected, limit):
                        clock.sleep_until(sim.t)
                        self.check()
                        return True
                    if limit is not None:
                        clock.sleep_until(limit)
                        return ready()
                elif clock.now() >= deadline:
                    return False
            # real time: a moment; instant time with nothing to run: only another thread can change it
            time.sleep(WALL_STEP if clock.rate is not None else IDLE_WAIT)
