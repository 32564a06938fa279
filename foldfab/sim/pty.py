"""A simulated plotter on a pseudo-terminal: any program talks to it as to hardware.

:func:`serve_pty` creates a pty, reports the path of its terminal side (``/dev/pts/N``,
which ``serial.Serial`` opens like a USB adapter) and serves a simulator
(:func:`foldfab.sim.create_simulator`) there until ``stop`` is set.  The server plays the wire: it takes the host's bytes off the pty no
faster than the baud rate allows, so the host's ``write`` blocks in the kernel as it
would on a real port, and it honours the flow control the host set on its side of the
pty (``IXON`` for XON/XOFF, ``CRTSCTS`` for RTS/CTS, which a pty has no lines for) by
leaving bytes in the kernel while the device says stop.  The pty is shared by every
program that opens it and the device does not notice opens (no ``reset_on_open``).
A ``disconnect_after`` fault closes the pty: the host sees the device vanish.  Every
time mode works: ``instant`` runs the device as fast as it can be simulated while the
host is silent.  Each job is reported as it ends (:meth:`Simulator.end_job`).
"""

from __future__ import annotations

import math
import os
import select
import termios
import threading
import tty
from typing import TYPE_CHECKING, Callable

from foldfab.sim.clock import IDLE_WAIT

if TYPE_CHECKING:
    from foldfab.sim.device import Simulator
    from foldfab.sim.record import JobRecord

READ_CHUNK = 4096
MIN_WAIT = 0.0005  # wall seconds: the shortest sleep of the serving loop
INSTANT_EVENTS = 1000  # instant time: device events run between two looks at the host


def serve_pty(sim: Simulator, ready: Callable[[str], None], stop: threading.Event,
              job_done: Callable[[JobRecord], None] = lambda job: None) -> None:
    """Serve ``sim`` on a new pty until ``stop`` is set (or the cable is pulled).

    ``ready(path)`` is called with the terminal's path once it can be opened; ``job_done``
    with each job as it ends (see :meth:`Simulator.end_job`), and with the one in progress
    when serving stops.
    """
    master, slave = os.openpty()
    try:
        tty.setraw(slave)
        os.set_blocking(master, False)
        ready(os.ttyname(slave))
        sim.connect()
        _serve(sim, master, slave, stop, job_done)
    finally:
        os.close(master)
        os.close(slave)
    job = sim.end_job(force=True)
    if job is not None:
        job_done(job)


def _serve(sim: Simulator, master: int, slave: int, stop: threading.Event,
           job_done: Callable[[JobRecord], None]) -> None:
    """The serving loop.  In ``instant`` time the virtual clock jumps: over the wire time of
    the bytes the host wrote, and, while the host is silent, to the device's next event, so
    the device runs as fast as it can be simulated and answers at once."""
    clock = sim.clock
    instant = clock.rate is None
    held = bytearray()  # taken off the pty, not yet on the wire: the host driver's buffer
    replies = bytearray()
    polled = clock.now()
    while not stop.is_set() and not sim.disconnected:
        sim.host_flow = _host_flow(slave)
        if not held:
            held += _read(master)
        if instant:
            if held:
                sent, until = sim.transmit(bytes(held), max(sim.wire_free, clock.now()))
                del held[:sent]
                clock.sleep_until(until)
            else:  # the host is silent: the device runs on (a bounded number of events at a time)
                for _ in range(INSTANT_EVENTS):
                    upcoming = min(sim.next_event(), sim.next_arrival())
                    if upcoming == math.inf:
                        break
                    clock.sleep_until(upcoming)
                    sim.advance(upcoming)
        now = clock.now()
        if held and not instant:
            sent, _ = sim.transmit(bytes(held), max(sim.wire_free, polled), now)
            del held[:sent]
        sim.advance(now)
        polled = now
        job = sim.end_job()
        if job is not None:
            job_done(job)
        replies += sim.take_output(sim.arrived)
        if replies:
            del replies[:_write(master, replies)]
        busy = min(sim.next_event(), sim.next_arrival()) < math.inf
        if instant:  # nothing to wait for but the host (or, while it is held back, a moment)
            wait = MIN_WAIT if held or busy else IDLE_WAIT
        else:
            wait = min(IDLE_WAIT, clock.wall(sim.byte_time) if held else IDLE_WAIT,
                       clock.wall(max(0.0, min(sim.next_event(), sim.next_arrival()) - now)))
        select.select([] if held else [master], [master] if replies else [], [],
                      max(wait, MIN_WAIT))


def _host_flow(slave: int) -> frozenset[str]:
    """The flow control the host configured on its side of the pty."""
    iflag, _, cflag, *_ = termios.tcgetattr(slave)
    return frozenset(name for name, on in (("xonxoff", iflag & termios.IXON),
                                           ("rtscts", cflag & termios.CRTSCTS)) if on)


def _read(master: int) -> bytes:
    try:
        return os.read(master, READ_CHUNK)
    except (BlockingIOError, InterruptedError):
        return b""


def _write(master: int, data: bytearray) -> int:
    try:
        return os.write(master, data)
    except (BlockingIOError, InterruptedError):
        return 0
