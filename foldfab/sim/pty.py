"""A simulated plotter on a pseudo-terminal: any program talks to it as to hardware.

:func:`serve_pty` creates a pty, reports the path of its terminal side (``/dev/pts/N``,
which ``serial.Serial`` opens like a USB adapter) and serves a simulator
(:func:`foldfab.sim.create_simulator`) there until ``stop`` is set.  The server plays the wire: it takes the host's bytes off the pty no
faster than the baud rate allows, so the host's ``write`` blocks in the kernel as it
would on a real port, and it honours the flow control the host set on its side of the
pty (``IXON`` for XON/XOFF, ``CRTSCTS`` for RTS/CTS, which a pty has no lines for) by
leaving bytes in the kernel while the device says stop.  The pty is shared by every
program that opens it and the device does not notice opens (no ``reset_on_open``).
A ``disconnect_after`` fault closes the pty: the host sees the device vanish.
"""

from __future__ import annotations

import os
import select
import termios
import threading
import tty
from typing import TYPE_CHECKING, Callable

from foldfab.errors import FoldfabError
from foldfab.sim.clock import IDLE_WAIT

if TYPE_CHECKING:
    from foldfab.sim.device import Simulator

READ_CHUNK = 4096
MIN_WAIT = 0.0005  # wall seconds: the shortest sleep of the serving loop


def serve_pty(sim: Simulator, ready: Callable[[str], None], stop: threading.Event) -> None:
    """Serve ``sim`` on a new pty until ``stop`` is set (or the cable is pulled).

    ``ready(path)`` is called with the terminal's path once it can be opened.
    """
    if sim.clock.rate is None:
        raise FoldfabError("a simulator on a pty runs on the wall clock: use time=real or "
                           "time=fast (instant needs the sim:// port)")
    master, slave = os.openpty()
    try:
        tty.setraw(slave)
        os.set_blocking(master, False)
        ready(os.ttyname(slave))
        sim.connect()
        _serve(sim, master, slave, stop)
    finally:
        os.close(master)
        os.close(slave)


def _serve(sim: Simulator, master: int, slave: int, stop: threading.Event) -> None:
    clock = sim.clock
    held = bytearray()  # taken off the pty, not yet on the wire: the host driver's buffer
    replies = bytearray()
    polled = clock.now()
    while not stop.is_set() and not sim.disconnected:
        now = clock.now()
        sim.host_flow = _host_flow(slave)
        if not held:
            held += _read(master)
        if held:
            sent, _ = sim.transmit(bytes(held), max(sim.wire_free, polled), now)
            del held[:sent]
        sim.advance(now)
        polled = now
        replies += sim.take_output(sim.arrived)
        if replies:
            del replies[:_write(master, replies)]
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
