"""pyserial URL handler ``lp:///dev/usb/lp0``: a USB printer-class device file as a port.

Cutters such as the Roland GX-24 appear on Linux as printer-class devices (``usblp``:
``/dev/usb/lp0``, on older systems ``/dev/usblp0``).  They are not terminals, so pyserial
cannot configure them (``Inappropriate ioctl for device``); this handler opens the file raw
and keeps pyserial's port API, so the streaming engines run unchanged.
:func:`foldfab.plotting.transport.open_port` uses it for any path that is not a terminal.

* ``write`` blocks while the cutter is busy (the driver takes no more until the device
  accepts the bulk transfer), polling so that ``cancel_write`` and Ctrl-C stop it; a write
  that makes no progress for ``write_timeout`` (default :data:`WRITE_STALL`) raises
  :class:`~serial.SerialTimeoutException` naming the printer status.
* ``read`` waits (``poll``) up to ``timeout``; ``in_waiting`` does not wait.
* The printer status (``LPGETSTATUS``, the IEEE 1284 status byte ``usblp`` reads from the
  device) is read while a write is held up or a read finds no answer (at most every
  :data:`STATUS_EVERY`): paper out, offline and error each stop the call with a message
  saying what to do.  Where the kernel gives no status (another kind
  of file) the write waits for its timeout.
* A pulled cable (``ENODEV``, ``EIO``, a hang-up) raises :class:`~serial.SerialException`
  "device disconnected".  Line settings (baud rate, parity, flow control) do not apply.
"""

from __future__ import annotations

import errno
import fcntl
import os
import select
import struct
import time
from urllib.parse import unquote, urlsplit

from serial.serialutil import PortNotOpenError, SerialException, SerialTimeoutException

from foldfab.plotting.urlhandler.rawport import SLICE, RawPort, check_bytes

LPGETSTATUS = 0x060B
"""linux/lp.h: the printer's status byte (``usblp`` answers it with GET_PORT_STATUS)."""
LP_PERRORP, LP_PSELECD, LP_POUTPA = 0x08, 0x10, 0x20
"""Status bits (linux/lp.h): no error (active low), selected (online), paper out."""
WRITE_STALL = 30.0
"""Seconds a write may make no progress, when the port has no ``write_timeout``."""
STATUS_EVERY = 0.5
"""Seconds between status reads while a write is held up."""
READ_CHUNK = 4096
GONE = (errno.ENODEV, errno.EIO, errno.EPIPE, errno.ENXIO, errno.ESHUTDOWN)


def printer_status(fd: int, path: str) -> int | None:
    """The device's IEEE 1284 status byte; None where the file has none."""
    try:
        return struct.unpack("i", fcntl.ioctl(fd, LPGETSTATUS, struct.pack("i", 0)))[0] & 0xFF
    except OSError as exc:
        if exc.errno in GONE:
            raise
    from foldfab.sim.printer import simulated_status  # a simulated device has no kernel driver

    return simulated_status(path)


def status_problem(status: int | None) -> str | None:
    """What a status byte says is wrong, with what to do; None if nothing is."""
    if status is None:
        return None
    if status & LP_POUTPA:
        return "paper out: load the sheet (or clear the media sensor)"
    if not status & LP_PSELECD:
        return "offline: put the cutter online (press its online/pause key)"
    if not status & LP_PERRORP:
        return "the cutter reports an error: see its display, clear it"
    return None


class Serial(RawPort):
    """A printer-class device file behind pyserial's port API."""

    def __init__(self, *args, **kwargs):
        self.fd: int | None = None
        self.path = ""
        self._asked = 0.0  # when the status was last read
        super().__init__(*args, **kwargs)

    def open(self) -> None:
        url = self._opening()
        parts = urlsplit(url)
        if parts.scheme != "lp" or not parts.path or parts.query:
            raise SerialException(f"{self._port}: expected lp:///dev/usb/lp0 (the device file's path)")
        self.path = unquote(parts.netloc + parts.path)
        try:
            self.fd = os.open(self.path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        except OSError as exc:
            raise SerialException(exc.errno, f"could not open {self.path}: {exc.strerror}") from None
        self._rx.clear()
        self.is_open = True

    def close(self) -> None:
        self._cancel.set()
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None
        self.is_open = False

    def _gone(self, why: str) -> SerialException:
        return SerialException(f"{self.path}: device disconnected ({why}): check the USB cable "
                               "and that the cutter is switched on")

    def _fd(self) -> int:
        if not self.is_open or self.fd is None:
            raise PortNotOpenError()
        return self.fd

    def _poll(self, events: int, seconds: float) -> bool:
        """Wait up to ``seconds`` for ``events``; a hang-up is a pulled cable."""
        poller = select.poll()
        poller.register(self._fd(), events | select.POLLHUP | select.POLLERR)
        for _, happened in poller.poll(max(seconds, 0.0) * 1000):
            if happened & events:
                return True
            if happened & (select.POLLHUP | select.POLLERR):
                raise self._gone("hang-up")
        return False

    def _fill(self) -> None:
        """Move what the device has sent into the input buffer (does not wait)."""
        while True:
            try:
                data = os.read(self._fd(), READ_CHUNK)
            except (BlockingIOError, InterruptedError):
                return
            except OSError as exc:
                if exc.errno in GONE:
                    raise self._gone(exc.strerror) from None
                raise SerialException(f"{self.path}: read failed: {exc.strerror}") from None
            if not data:
                raise self._gone("end of file")
            self._rx += data

    def _receive(self, seconds: float) -> None:
        if self._poll(select.POLLIN, seconds):
            self._fill()

    def _answerless(self) -> None:
        self._check_status()  # a device out of paper or offline does not answer: say why

    def write(self, data) -> int:
        data = memoryview(check_bytes(data))
        fd = self._fd()
        self._cancel.clear()
        limit = WRITE_STALL if self._write_timeout is None else self._write_timeout
        done, progress = 0, time.monotonic()
        while done < len(data) and not self._cancel.is_set():
            if self._poll(select.POLLOUT, SLICE):
                try:
                    count = os.write(fd, data[done:])
                except (BlockingIOError, InterruptedError):
                    count = 0
                except OSError as exc:
                    if exc.errno in GONE:
                        raise self._gone(exc.strerror) from None
                    if exc.errno == errno.ENOSPC:  # usblp: the device reports paper out
                        raise SerialException(f"{self.path}: paper out: load the sheet, then resume") from None
                    raise SerialException(f"{self.path}: write failed: {exc.strerror}") from None
                if count:
                    done, progress = done + count, time.monotonic()
                    continue
            self._check_status()  # held up: does the device say why?
            if time.monotonic() - progress > limit:
                raise SerialTimeoutException(
                    f"{self.path}: the cutter took no data for {limit:g} s after {done} of {len(data)} "
                    "bytes (busy: a jam, its pause key, or hung?)")
        return done

    def _check_status(self) -> None:
        """Read the printer status (at most every :data:`STATUS_EVERY`); a problem it reports
        stops the call with what to do."""
        now = time.monotonic()
        if now - self._asked < STATUS_EVERY:
            return
        self._asked = now
        problem = status_problem(printer_status(self._fd(), self.path))
        if problem:
            raise SerialException(f"{self.path}: {problem}, then resume")
