"""pyserial URL handler ``sim://DEVICE?option=value&...``: a simulated plotter as a port.

``DEVICE`` is a device profile name or path (:func:`foldfab.devices.load_device`);
the options are :mod:`foldfab.sim.options`.  The simulator is ``port.simulator``
(strokes, stats, write_svg, to_json, device).  Assign a profile to ``port.profile``
before ``open()`` to simulate it under ``sim://`` with no name, or an existing
simulator to ``port.simulator`` to plug the cable back into the same device; the
``session=NAME`` option does the same by name (every open with that session in this
process reaches the plotter the first one created).  The plotter runs on while no port
is open to it: opening one brings it up to the clock's present first, so the reset of a
GRBL board at open finds the moves that ended meanwhile ended (no ``ALARM:3``).  With
``power_cycle=1`` the second open finds it switched off and on: a fresh simulator takes
its place (in ``port.simulator`` and the session; the old one keeps what it drew).

The port's settings act as a host driver's would: ``baudrate``, ``bytesize``,
``parity`` and ``stopbits`` set the wire time; with ``xonxoff`` the driver stops
sending on XOFF and swallows XON/XOFF; with ``rtscts`` it stops while CTS is low.
In ``real`` and ``fast`` time the port has a driver's transmit buffer
(:data:`DRIVER_BUFFER` bytes, as a Linux serial port): ``write`` returns once what is
left of its bytes fits in it, and the wire carries them on the plotter's clock whether the
host runs or not (every later call on the port delivers what has arrived meanwhile, in
order, at the times it arrived), so a host busy elsewhere costs the link nothing while
its driver holds bytes; ``flush`` waits until they are through, ``out_waiting`` counts
them, ``reset_output_buffer`` drops them and ``close`` lets them go out.  In ``instant``
time ``write`` returns when its last byte has arrived.  With ``write_timeout`` it raises
:class:`~serial.SerialTimeoutException` when flow control holds it longer.
In ``instant`` time a poll that finds nothing (``in_waiting``, ``cts``, ``read``
with ``timeout=0``) lets ``POLL_STEP`` of virtual time pass, as a polling host's
sleep would, once ``FREE_LOOKS`` polls at the same moment found nothing; instant time assumes one thread drives the port (real and fast time
are thread-safe: a reader and a writer thread may share it).  Timeouts are virtual
seconds.  ``inter_byte_timeout``, RTS, DTR and breaks are not simulated.  After
``disconnect_after`` bytes every call raises :class:`~serial.SerialException`, as
with a pulled cable.
"""

from __future__ import annotations

import math
import threading
from typing import TYPE_CHECKING, Callable
from urllib.parse import parse_qsl, unquote, urlsplit

from serial.serialutil import PortNotOpenError, SerialBase, SerialException, SerialTimeoutException

from foldfab.sim.clock import IDLE_WAIT

if TYPE_CHECKING:
    from foldfab.sim.device import Simulator

POLL_STEP = 0.01
"""Virtual seconds an empty poll lets pass in ``instant`` time (see :data:`FREE_LOOKS`)."""
FREE_LOOKS = 2
"""Empty polls at one moment of ``instant`` time that let no time pass: a host that looks
before it acts costs the plotter nothing, as on a real port; one that keeps looking is
sleeping between its looks, and each further look lets :data:`POLL_STEP` pass."""
_SESSIONS: dict[str, Simulator] = {}
"""Simulators by ``session`` option: a later open plugs into the same plotter."""
_SESSIONS_LOCK = threading.Lock()
DRIVER_BUFFER = 4096
"""Bytes the simulated host driver holds for the wire (Linux keeps a page per serial port,
for UARTs and USB adapters alike); a write blocks while more than this is still to go."""
WALL_STEP = 0.002
"""Longest wall-clock sleep of a blocking call in real and fast time, so that a reply
caused by another thread's write is seen at once (ports are shared by a reader and a
writer thread; the lock keeps the simulator consistent)."""


def _switched_on(old: Simulator) -> Simulator:
    """A fresh simulator for ``old``'s plotter after a power cycle; the session reaches it from now on."""
    from foldfab.sim import create_simulator

    new = create_simulator(old.device, old.options.switched_on())
    with _SESSIONS_LOCK:
        if _SESSIONS.get(old.options.session) is old:
            _SESSIONS[old.options.session] = new
    return new


class Serial(SerialBase):
    """A simulated plotter behind pyserial's port API."""

    def __init__(self, *args, **kwargs):
        self.simulator: Simulator | None = None
        self.profile = None  # a DeviceProfile for "sim://" without a name
        self._cancel = threading.Event()
        self._lock = threading.RLock()
        self._pending = bytearray()  # written, not yet through the wire (real and fast time)
        self._polled_at: float | None = None  # instant time: when a poll last found nothing
        self._looks = 0  # how many found nothing then
        self._pending_start = 0.0  # virtual time they were written at (they follow the wire's last byte)
        super().__init__(*args, **kwargs)

    def open(self) -> None:
        from foldfab.errors import FoldfabError

        if self.is_open:
            raise SerialException("Port is already open.")
        if self._port is None:
            raise SerialException("Port must be configured before it can be used.")
        if self.simulator is None:
            try:
                self.simulator = self._create(self._port)
            except FoldfabError as exc:
                raise SerialException(str(exc)) from None
        if self.simulator.options.power_cycle and self.simulator.opened:
            self.simulator = _switched_on(self.simulator)
        self.simulator.opened += 1
        with self._lock:
            # The board ran on while no port was open (a session's or a given simulator): bring
            # it up to now first, so that the reset at open sees the moves that are over as over.
            self.simulator.advance(self.simulator.clock.now())
            self.simulator.disconnected = False  # the cable is back in, with a fresh driver
            self.simulator.xoff = False
            self.is_open = True
            self._reconfigure_port()
            self.simulator.connect()

    def _create(self, url: str) -> Simulator:
        from foldfab.devices import load_device
        from foldfab.errors import FoldfabError
        from foldfab.sim import create_simulator, parse_options

        parts = urlsplit(url)
        if parts.scheme != "sim":
            raise FoldfabError(f"{url}: expected sim://DEVICE?option=value&...")
        name = unquote(parts.netloc + parts.path)
        if not name and self.profile is None:
            raise FoldfabError(f"{url}: no device: name one (sim://grbl) or open it with a "
                               "device profile (foldfab.plotting.transport.open_port)")
        options = parse_options(parse_qsl(parts.query, keep_blank_values=True), url)
        with _SESSIONS_LOCK:
            if options.session in _SESSIONS:
                return _SESSIONS[options.session]
            simulator = create_simulator(load_device(name) if name else self.profile, options)
            if options.session is not None:
                _SESSIONS[options.session] = simulator
            return simulator

    def close(self) -> None:
        """Close the port; the bytes the driver still holds go out (as a driver drains at close)."""
        with self._lock:
            if self.is_open and self._pending and not self.simulator.disconnected:
                self.simulator.transmit(bytes(self._pending), self._pending_start)
            self._pending.clear()
            self.is_open = False
        self._cancel.set()

    def _reconfigure_port(self) -> None:
        sim = self.simulator
        if sim is None or not self.is_open:
            return
        if not isinstance(self._baudrate, int) or self._baudrate <= 0:
            raise ValueError(f"invalid baudrate: {self._baudrate!r}")
        sim.configure_wire(self._baudrate, self._bytesize, self._parity, self._stopbits)
        sim.host_flow = frozenset(name for name, on in
                                  (("xonxoff", self._xonxoff), ("rtscts", self._rtscts)) if on)
        sim.swallow_flow_bytes = bool(self._xonxoff)

    # --- data ---------------------------------------------------------------------------

    def _live(self) -> Simulator:
        """The simulator, brought up to the host's time; raises if closed or unplugged."""
        if not self.is_open:
            raise PortNotOpenError()
        sim = self.simulator
        now = sim.clock.now()
        if self._pending and not sim.disconnected:  # the wire carried them meanwhile, before anything else
            sent, _ = sim.transmit(bytes(self._pending), self._pending_start, now)
            del self._pending[:sent]
        if sim.disconnected:
            self._pending.clear()
            raise SerialException(f"{self._port}: device disconnected (cable pulled after "
                                  f"{sim.stats.bytes_received} bytes)")
        sim.advance(now)
        return sim

    def _poll(self, sim: Simulator) -> None:
        """An empty poll: in instant time, let a moment pass if the host keeps looking (see FREE_LOOKS)."""
        clock = sim.clock
        if clock.rate is None:
            if self._polled_at != clock.now():
                self._polled_at, self._looks = clock.now(), 0
            self._looks += 1
            if self._looks > FREE_LOOKS:
                clock.sleep_until(clock.now() + POLL_STEP)
                sim.advance(clock.now())
                self._polled_at, self._looks = clock.now(), 0

    def _wait(self, sim: Simulator, deadline: float | None, ready: Callable[[], bool]) -> None:
        """Block until ``ready()``, the virtual ``deadline``, or a moment (see WALL_STEP)."""
        clock = sim.clock
        if clock.rate is None:  # instant: run ahead to the event
            with self._lock:
                if sim.run_until(ready, deadline):
                    clock.sleep_until(sim.t)
                    return
                if deadline is not None:
                    clock.sleep_until(deadline)
                    return
            self._cancel.wait(IDLE_WAIT)  # nothing will ever happen: wait for cancel or close
            return
        wake = min(sim.next_event(), sim.next_arrival(), math.inf if deadline is None else deadline)
        self._cancel.wait(min(WALL_STEP, clock.wall(max(0.0, wake - clock.now()))))
        with self._lock:
            self._live()

    @property
    def in_waiting(self) -> int:
        with self._lock:
            sim = self._live()
            if not sim.arrived:
                self._poll(sim)
            return sim.arrived

    def read(self, size: int = 1) -> bytes:
        with self._lock:
            sim = self._live()
            self._cancel.clear()
            clock = sim.clock
            deadline = None if self._timeout is None else clock.now() + self._timeout
            data = bytearray(sim.take_output(size))
            if not data and self._timeout == 0:
                self._poll(sim)
        while len(data) < size and self._timeout != 0 and not self._cancel.is_set():
            self._wait(sim, deadline, lambda: sim.arrived > 0)
            with self._lock:
                data += self._live().take_output(size - len(data))
            if deadline is not None and clock.now() >= deadline:
                break
        return bytes(data)

    def write(self, data) -> int:
        if isinstance(data, int) or not isinstance(data, (bytes, bytearray, memoryview)):
            raise TypeError(f"write() takes bytes, not {type(data).__name__} "
                            "(pyserial's write(int) would send that many zero bytes)")
        data = bytes(data)
        with self._lock:
            sim = self._live()
            self._cancel.clear()
            clock = sim.clock
            start = clock.now()
            deadline = None if self._write_timeout is None else start + self._write_timeout
        if clock.rate is not None:  # real and fast time: into the driver's buffer
            return self._queue(sim, data, start, deadline)
        done = 0
        while done < len(data) and not self._cancel.is_set():
            with self._lock:
                self._live()
                sent, until = sim.transmit(data[done:], start, deadline)  # instant: the whole write at once
                clock.sleep_until(until)
                done += sent
                if sim.disconnected and done < len(data):
                    self._live()  # raises
            if done < len(data):
                if deadline is not None and clock.now() >= deadline - sim.byte_time:
                    raise SerialTimeoutException("Write timeout")
                self._wait(sim, deadline, lambda: not sim.host_stopped())
        return done

    def _queue(self, sim: Simulator, data: bytes, start: float, deadline: float | None) -> int:
        """Add ``data`` to the driver's buffer; block while more than :data:`DRIVER_BUFFER` bytes
        are still to go.  Returns the bytes taken (fewer after a cancel or a write timeout)."""
        with self._lock:
            if not self._pending:
                self._pending_start = start
            self._pending += data
        while True:
            with self._lock:
                excess = len(self._pending) - DRIVER_BUFFER
                if excess <= 0:
                    return len(data)
                if self._cancel.is_set() or (deadline is not None and sim.clock.now() >= deadline):
                    del self._pending[DRIVER_BUFFER:]
                    if self._cancel.is_set():
                        return len(data) - excess
                    raise SerialTimeoutException("Write timeout")
            self._wait(sim, deadline, lambda: len(self._pending) <= DRIVER_BUFFER)

    def flush(self) -> None:
        """Wait until the bytes the driver holds are through the wire (or the port is closed)."""
        with self._lock:
            sim = self._live()
        while self._pending and not self._cancel.is_set():
            self._wait(sim, None, lambda: not self._pending)

    @property
    def out_waiting(self) -> int:
        """Bytes the driver holds, not through the wire yet."""
        with self._lock:
            self._live()
            return len(self._pending)

    def reset_input_buffer(self) -> None:
        with self._lock:
            self._live().discard_arrived()

    def reset_output_buffer(self) -> None:
        """Drop the bytes the driver still holds."""
        with self._lock:
            self._live()
            self._pending.clear()

    def cancel_read(self) -> None:
        self._cancel.set()

    def cancel_write(self) -> None:
        self._cancel.set()

    # --- modem lines --------------------------------------------------------------------

    @property
    def cts(self) -> bool:
        with self._lock:
            sim = self._live()
            if not sim.cts:
                self._poll(sim)
            return sim.cts

    @property
    def dsr(self) -> bool:
        return not self._live().options.mute

    @property
    def ri(self) -> bool:
        self._live()
        return False

    @property
    def cd(self) -> bool:
        self._live()
        return True

    def _update_rts_state(self) -> None:
        """Not simulated: the device never stops sending its short replies."""

    def _update_dtr_state(self) -> None:
        """Not simulated (``reset_on_open`` models the Arduino reset at open)."""

    def _update_break_state(self) -> None:
        """Not simulated."""
