"""What the ``lp://`` and ``usb://`` handlers share: a port to a device that is no terminal.

A printer-class device file and a USB cutter's bulk endpoints have no line settings and no
modem lines; :class:`RawPort` gives them pyserial's port API on two primitives a subclass
provides: :meth:`RawPort._receive` (move what the device sent into the input buffer, waiting
up to a time) and ``write``.
"""

from __future__ import annotations

import threading
import time

from serial.serialutil import SerialBase, SerialException

SLICE = 0.05
"""Seconds of one wait: how soon a cancel or a status change is seen."""


def check_bytes(data) -> bytes:
    """``data`` as bytes; an int or str is refused (pyserial's write(int) sends that many zeros)."""
    if isinstance(data, int) or not isinstance(data, (bytes, bytearray, memoryview)):
        raise TypeError(f"write() takes bytes, not {type(data).__name__} "
                        "(pyserial's write(int) would send that many zero bytes)")
    return bytes(data)


class RawPort(SerialBase):
    """pyserial's port API over :meth:`_receive` and ``write`` (see the module docstring)."""

    def __init__(self, *args, **kwargs):
        self._rx = bytearray()
        self._cancel = threading.Event()
        super().__init__(*args, **kwargs)

    def _opening(self) -> str:
        """The URL to open; raises if the port is open already or has none."""
        if self.is_open:
            raise SerialException("Port is already open.")
        if self._port is None:
            raise SerialException("Port must be configured before it can be used.")
        return self._port

    def _receive(self, seconds: float) -> None:
        """Add what the device has sent to ``self._rx``, waiting up to ``seconds`` for it."""
        raise NotImplementedError

    def _answerless(self) -> None:
        """A read found too little: a subclass may ask the device why (and raise)."""

    @property
    def in_waiting(self) -> int:
        if not self._rx:
            self._receive(0)
        return len(self._rx)

    def read(self, size: int = 1) -> bytes:
        self._cancel.clear()
        deadline = None if self._timeout is None else time.monotonic() + self._timeout
        while len(self._rx) < size and not self._cancel.is_set():
            left = SLICE if deadline is None else min(SLICE, deadline - time.monotonic())
            if left <= 0:
                break
            self._receive(left)
        if len(self._rx) < size:
            self._answerless()
        data = bytes(self._rx[:size])
        del self._rx[:size]
        return data

    def flush(self) -> None:
        """``write`` returns when the device (or its driver) has taken everything."""

    def reset_input_buffer(self) -> None:
        self._receive(0)
        self._rx.clear()

    def reset_output_buffer(self) -> None:
        """Nothing is held back on the host's side."""

    def cancel_read(self) -> None:
        self._cancel.set()

    def cancel_write(self) -> None:
        self._cancel.set()

    def _reconfigure_port(self) -> None:
        """Nothing to configure: no line settings."""

    # --- modem lines: there are none; report them as a plain cable would --------------------------
    @property
    def cts(self) -> bool:
        return True

    @property
    def dsr(self) -> bool:
        return True

    @property
    def ri(self) -> bool:
        return False

    @property
    def cd(self) -> bool:
        return True

    def _update_rts_state(self) -> None:
        """No modem lines."""

    def _update_dtr_state(self) -> None:
        """No modem lines."""

    def _update_break_state(self) -> None:
        """No modem lines."""
