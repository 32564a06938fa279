"""A simulated USB printer-class device (``/dev/usb/lp0``) that a program opens as a file.

:func:`serve_printer` serves any foldfab simulator behind a :class:`~foldfab.sim.usblink.UsbLink`
on a pseudo-terminal set raw: its terminal side is the "device file".  A pty rather than a
FIFO pair or a socket because it is one path that opens read-write with ``open()``, as
``/dev/usb/lp0`` does (a FIFO is one-way, a socket cannot be opened), its kernel buffer
blocks the writer when the server stops taking bytes, as ``usblp`` blocks while the cutter
is busy, and closing its other side makes the writer's next call fail with ``EIO``, as a
pulled cable makes ``usblp``'s fail with ``ENODEV``.  The server takes bytes off the pty only
as the device has room (so nothing is lost: the host's ``write`` blocks instead), and writes
the device's answers back.  Paper out and busy come from the link (``paper_out``, the
simulator's ``stall``); ``disconnect_after`` closes the pty.

A pty has no ``LPGETSTATUS`` ioctl: the printer status of a served device is registered
under its path (:func:`simulated_status`), where the ``lp://`` handler looks when the kernel
gives none.  Only open with ``lp://PATH``: the path is a terminal, so a bare path would be
opened as a serial port.
"""

from __future__ import annotations

import os
import select
import threading
import tty
from typing import TYPE_CHECKING, Callable

from foldfab.sim.clock import IDLE_WAIT
from foldfab.sim.pty import _write
from foldfab.sim.usblink import Unplugged, UsbLink

if TYPE_CHECKING:
    from foldfab.sim.device import Simulator

READ_CHUNK = 4096
PRINTER_FIFO = 512
"""Bytes the simulated printer's endpoint holds beyond its command buffer."""
MIN_WAIT = 0.0005  # wall seconds: the shortest sleep of the serving loop
_STATUS: dict[str, Callable[[], int]] = {}
_STATUS_LOCK = threading.Lock()


def simulated_status(path: str) -> int | None:
    """The printer status byte of the simulated device served at ``path``; None if none is."""
    with _STATUS_LOCK:
        status = _STATUS.get(os.path.realpath(path))
    return status() if status is not None else None


def serve_printer(link: UsbLink, ready: Callable[[str], None], stop: threading.Event) -> None:
    """Serve ``link``'s simulator as a printer-class device until ``stop`` is set or the
    cable is pulled; ``ready(path)`` is called once the path can be opened."""
    master, slave = os.openpty()
    path = os.ttyname(slave)
    try:
        tty.setraw(slave)
        os.set_blocking(master, False)
        with _STATUS_LOCK:
            _STATUS[os.path.realpath(path)] = link.status
        link.sim.connect()
        ready(path)
        _serve(link, master, stop)
    finally:
        with _STATUS_LOCK:
            _STATUS.pop(os.path.realpath(path), None)
        os.close(master)  # the host's next call fails with EIO: the device is gone
        os.close(slave)
    link.sim.end_job(force=True)


def printer_thread(sim: Simulator, paper_out_after: int | None = None
                   ) -> tuple[str, UsbLink, threading.Event, threading.Thread]:
    """Serve ``sim`` as a printer device on a daemon thread: (path, link, stop event, thread)."""
    link = UsbLink(sim, paper_out_after, fifo=PRINTER_FIFO)
    stop, opened, found = threading.Event(), threading.Event(), []

    def ready(path: str) -> None:
        found.append(path)
        opened.set()

    thread = threading.Thread(target=serve_printer, args=(link, ready, stop), daemon=True,
                              name="simulated printer device")
    thread.start()
    if not opened.wait(10):
        raise RuntimeError("the simulated printer device did not start")
    return found[0], link, stop, thread


def _serve(link: UsbLink, master: int, stop: threading.Event) -> None:
    """The serving loop: host bytes in as the device has room, answers out, the device run on."""
    replies = bytearray()
    while not stop.is_set():
        try:
            room = link.room()
            if room:
                data = _take(master, min(room, READ_CHUNK))
                if data:
                    link.accept(data)
            link.run_on()
            replies += link.take(READ_CHUNK)
        except Unplugged:
            return
        if replies:
            del replies[:_write(master, replies)]
        sim = link.sim
        busy = min(sim.next_event(), sim.next_arrival()) < float("inf")
        if sim.clock.rate is None:
            wait = MIN_WAIT if busy or not room else IDLE_WAIT
        else:
            wait = min(IDLE_WAIT, sim.clock.wall(max(0.0, min(sim.next_event(), sim.next_arrival())
                                                     - sim.clock.now())))
        select.select([master] if room else [], [master] if replies else [], [], max(wait, MIN_WAIT))


def _take(master: int, size: int) -> bytes:
    """Up to ``size`` of the host's bytes off the pty (the rest stay in the kernel)."""
    try:
        return os.read(master, size)
    except (BlockingIOError, InterruptedError):
        return b""
