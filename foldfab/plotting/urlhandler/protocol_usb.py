"""pyserial URL handler ``usb://VVVV:PPPP``: a cutter on raw USB (pyusb) as a port.

Silhouette cutters (and Graphtec's craft cutters) have no serial port: they are USB devices
with a bulk OUT endpoint for commands and a bulk IN endpoint for answers.  URLs:

* ``usb://0b4d:1137``: the first device with that vendor and product id (hexadecimal);
* ``usb://0b4d:1137?serial=ABC123``: the one with that serial number, among several;
* ``usb://silhouette``: the first Silhouette found (vendor 0x0b4d).

Opening finds the device, detaches the kernel driver that holds its interface (``usblp``
takes Silhouettes as printers), claims the interface and finds its bulk endpoints.  Writes
go a packet at a time (a packet is never half sent, so a transfer that times out sent
exactly the packets before it) and wait while the cutter is busy; one that makes no progress
for ``write_timeout`` (default :data:`WRITE_STALL`) raises
:class:`~serial.SerialTimeoutException`.  Reads wait up to ``timeout``.  A pulled cable
(``ENODEV``, ``EPIPE``, ``EIO``) raises :class:`~serial.SerialException` "device disconnected".
Errors say what to do: permissions (the udev rule :data:`UDEV_RULE`), device not found
(the USB devices foldfab sees), no libusb.

pyusb picks libusb itself; :data:`BACKEND` replaces it (tests put a simulated cutter there:
:class:`foldfab.sim.usb.SimulatedUsbBackend`), and so does the environment variable
:data:`SIM_VARIABLE`: ``FOLDFAB_USB_SIM="silhouette-cameo-4?time=fast"`` puts a simulated
cutter for that profile (with its USB ids) on the bus of every ``usb://`` URL of the
process, to try a whole plot without the cutter.
"""

from __future__ import annotations

import errno
import time
from urllib.parse import parse_qsl, unquote, urlsplit

from serial.serialutil import PortNotOpenError, SerialException, SerialTimeoutException

from foldfab.devices.usb import SILHOUETTE_VENDOR, usb_cutter
from foldfab.plotting.urlhandler.rawport import SLICE, RawPort, check_bytes

BACKEND = None
"""The pyusb backend to find devices with (None: pyusb's default, libusb)."""
SIM_VARIABLE = "FOLDFAB_USB_SIM"
_SIMULATED: dict[str, object] = {}
"""Simulated buses by the value of :data:`SIM_VARIABLE`: one cutter per process and value."""
WRITE_STALL = 30.0
"""Seconds a write may make no progress, when the port has no ``write_timeout``."""
SERIAL_LIMIT = 64
"""Characters of a device's serial number kept."""
GONE = (errno.ENODEV, errno.EPIPE, errno.EIO, errno.ESHUTDOWN, errno.ENXIO)
LIBUSB_GONE = (-4, -9, -1)  # LIBUSB_ERROR_NO_DEVICE, _PIPE, _IO
UDEV_RULE = ('SUBSYSTEM=="usb", ATTR{idVendor}=="0b4d", MODE="0660", GROUP="plugdev", TAG+="uaccess"')
"""A udev rule that lets the logged-in user (and group plugdev) use Silhouette cutters."""


def parse_usb_url(url: str) -> tuple[int, int | None, str | None]:
    """(vendor, product or None for any, serial or None) from a ``usb://`` URL."""
    parts = urlsplit(url)
    target = unquote(parts.netloc + parts.path).strip("/").lower()
    query = dict(parse_qsl(parts.query, keep_blank_values=True))
    unknown = set(query) - {"serial"}
    if parts.scheme != "usb" or unknown or not target:
        raise ValueError(f"{url}: expected usb://VENDOR:PRODUCT (hexadecimal ids, e.g. usb://0b4d:1137), "
                         "usb://silhouette, and optionally ?serial=...")
    if target == "silhouette":
        return SILHOUETTE_VENDOR, None, query.get("serial")
    vendor, _, product = target.partition(":")
    try:
        ids = int(vendor, 16), int(product, 16)
    except ValueError:
        ids = (-1, -1)
    if not all(0 <= i <= 0xFFFF for i in ids) or len(vendor) > 4 or len(product) > 4:
        raise ValueError(f"{url}: expected usb://VENDOR:PRODUCT with 4-digit hexadecimal ids "
                         "(usb://0b4d:1137) or usb://silhouette")
    return ids[0], ids[1], query.get("serial")


def usb_devices(backend=None) -> list:
    """Every USB device pyusb sees (raises SerialException if it has no backend)."""
    import usb.core

    try:
        return list(usb.core.find(find_all=True, backend=backend or BACKEND or _simulated_bus()))
    except usb.core.NoBackendError:
        raise SerialException("pyusb finds no libusb: install it (Debian: apt-get install "
                              "libusb-1.0-0)") from None


def _simulated_bus():
    """The simulated bus :data:`SIM_VARIABLE` asks for (None: it is not set)."""
    import os

    spec = os.environ.get(SIM_VARIABLE, "").strip()
    if not spec:
        return None
    if spec not in _SIMULATED:
        from foldfab.errors import FoldfabError
        from foldfab.sim.usb import SimulatedUsbBackend, simulated_cutter

        try:
            _SIMULATED[spec] = SimulatedUsbBackend([simulated_cutter(spec)])
        except FoldfabError as exc:
            raise SerialException(f"{SIM_VARIABLE}={spec}: {exc}") from None
    return _SIMULATED[spec]


def describe(dev) -> str:
    """``0b4d:1137 (Silhouette Cameo 4, serial X)`` for a pyusb device."""
    cutter = usb_cutter(dev.idVendor, dev.idProduct)
    serial = _serial(dev)
    what = ", ".join(filter(None, [cutter.model if cutter else None, f"serial {serial}" if serial else None]))
    return f"{dev.idVendor:04x}:{dev.idProduct:04x}" + (f" ({what})" if what else "")


def _serial(dev) -> str | None:
    import usb.core
    import usb.util

    try:
        text = usb.util.get_string(dev, dev.iSerialNumber) if dev.iSerialNumber else None
    except (usb.core.USBError, ValueError, NotImplementedError):
        return None  # no permission to ask, or no strings
    # the device's own text: printable characters only, bounded (it is printed and put in URLs)
    text = "".join(c for c in text or "" if c.isprintable() and c not in "&?#/")[:SERIAL_LIMIT]
    return text or None


class Serial(RawPort):
    """A USB cutter's bulk endpoints behind pyserial's port API."""

    def __init__(self, *args, **kwargs):
        self.device = None
        self._out = self._in = None
        self._interface = 0
        super().__init__(*args, **kwargs)

    # --- opening --------------------------------------------------------------------------
    def open(self) -> None:
        import usb.core
        import usb.util

        url = self._opening()
        try:
            vendor, product, serial = parse_usb_url(url)
        except ValueError as exc:
            raise SerialException(str(exc)) from None
        found = usb_devices()
        matching = [d for d in found if d.idVendor == vendor and product in (None, d.idProduct)
                    and (serial is None or _serial(d) == serial)]
        if not matching:
            seen = ", ".join(describe(d) for d in found) or "none"
            raise SerialException(f"no USB device {self._port.split('://', 1)[1]} is connected (USB "
                                  f"devices foldfab sees: {seen}); check the cable and that the cutter "
                                  "is switched on (foldfab ports)")
        dev = matching[0]
        try:
            self._claim(dev)
        except usb.core.USBError as exc:
            usb.util.dispose_resources(dev)
            raise self._failed(exc, "open") from None
        self.device = dev
        self._rx.clear()
        self.is_open = True

    def _claim(self, dev) -> None:
        import usb.core
        import usb.util

        try:
            config = dev.get_active_configuration()
        except usb.core.USBError:
            dev.set_configuration()
            config = dev.get_active_configuration()
        interface = config[(0, 0)]
        self._interface = interface.bInterfaceNumber
        if dev.is_kernel_driver_active(self._interface):
            dev.detach_kernel_driver(self._interface)
        usb.util.claim_interface(dev, self._interface)

        def endpoint(direction):
            return usb.util.find_descriptor(interface, custom_match=lambda e: (
                usb.util.endpoint_direction(e.bEndpointAddress) == direction
                and usb.util.endpoint_type(e.bmAttributes) == usb.util.ENDPOINT_TYPE_BULK))
        self._out, self._in = endpoint(usb.util.ENDPOINT_OUT), endpoint(usb.util.ENDPOINT_IN)
        if self._out is None:
            raise usb.core.USBError("the device has no bulk OUT endpoint: not a cutter foldfab can drive")

    def _failed(self, exc, doing: str) -> SerialException:
        """The SerialException for a pyusb error, saying what to do."""
        code = getattr(exc, "errno", None)
        if code in (errno.EACCES, errno.EPERM) or getattr(exc, "backend_error_code", None) == -3:
            return SerialException(f"{self._port}: permission denied: let your user use the cutter with a "
                                   f"udev rule, /etc/udev/rules.d/70-foldfab.rules: {UDEV_RULE} (then "
                                   "sudo udevadm control --reload and plug it in again)")
        if code in GONE or getattr(exc, "backend_error_code", None) in LIBUSB_GONE:
            return SerialException(f"{self._port}: device disconnected ({exc}): check the USB cable "
                                   "and that the cutter is switched on")
        if code == errno.EBUSY:
            return SerialException(f"{self._port}: the cutter is in use by another program: close it")
        return SerialException(f"{self._port}: USB {doing} failed: {exc}")

    def close(self) -> None:
        import usb.core
        import usb.util

        self._cancel.set()
        if self.device is not None:
            try:
                usb.util.release_interface(self.device, self._interface)
            except usb.core.USBError:
                pass  # unplugged: nothing to release
            usb.util.dispose_resources(self.device)
            self.device = None
        self.is_open = False

    def _dev(self):
        if not self.is_open or self.device is None:
            raise PortNotOpenError()
        return self.device

    # --- data -------------------------------------------------------------------------------
    def _receive(self, seconds: float) -> None:
        """One bulk IN transfer (libusb takes a timeout of 0 as "no limit": at least 1 ms)."""
        import usb.core

        if self._in is None:
            return
        try:
            data = self._dev().read(self._in.bEndpointAddress, self._in.wMaxPacketSize * 64,
                                    max(int(seconds * 1000), 1))
        except usb.core.USBTimeoutError:
            return
        except usb.core.USBError as exc:
            raise self._failed(exc, "read") from None
        self._rx += bytes(data)

    def write(self, data) -> int:
        import usb.core

        data = check_bytes(data)
        dev = self._dev()
        self._cancel.clear()
        limit = WRITE_STALL if self._write_timeout is None else self._write_timeout
        packet = self._out.wMaxPacketSize
        done, progress = 0, time.monotonic()
        while done < len(data) and not self._cancel.is_set():
            try:
                done += dev.write(self._out.bEndpointAddress, data[done:done + packet], int(SLICE * 1000))
                progress = time.monotonic()
            except usb.core.USBTimeoutError:
                if time.monotonic() - progress > limit:
                    raise SerialTimeoutException(
                        f"{self._port}: the cutter took no data for {limit:g} s after {done} of {len(data)} "
                        "bytes (busy: a jam, its pause key, an empty tray, or hung?)") from None
            except usb.core.USBError as exc:
                raise self._failed(exc, "write") from None
        return done
