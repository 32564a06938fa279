"""Opening a plotter's port: device paths and pyserial URLs, with the profile's line settings.

:func:`open_port` opens anything pyserial opens (``/dev/ttyUSB0``, ``socket://host:23``,
``rfc2217://...``, ``spy://...``) and foldfab's own handlers: ``sim://`` simulators,
``lp://`` USB printer-class devices (a path that is not a terminal, such as
``/dev/usb/lp0``, opens as ``lp://``) and ``usb://`` cutters on raw USB; it applies the
device profile's ``[serial]`` settings and turns every failure into one
:class:`~foldfab.errors.FoldfabError` naming the port and what to do.

pyserial reports an ImportError inside a URL handler only as "protocol not known",
so foldfab imports its own handler module first and lets its real error through.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from foldfab.errors import FoldfabError

if TYPE_CHECKING:
    import serial

    from foldfab.devices import DeviceProfile

HANDLER_PACKAGE = "foldfab.plotting.urlhandler"
DEFAULT_TIMEOUT = 1.0
"""Seconds a read waits by default: a plotter that does not answer must not hang foldfab."""


def register_handlers() -> None:
    """Let ``serial.serial_for_url`` find foldfab's URL handlers (``sim://``)."""
    import serial

    if HANDLER_PACKAGE not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(HANDLER_PACKAGE)


def open_port(url: str, device: DeviceProfile | None = None, *, baudrate: int | None = None,
              xonxoff: bool | None = None, rtscts: bool | None = None,
              dsrdtr: bool | None = None, timeout: float | None = DEFAULT_TIMEOUT,
              write_timeout: float | None = None) -> serial.SerialBase:
    """Open ``url`` (a device path or pyserial URL) with ``device``'s serial settings.

    The keyword arguments override the profile; without a profile pyserial's defaults
    (9600 8N1, no flow control) apply, except that ``sim://NAME`` uses NAME's profile.
    ``sim://`` without a device name simulates ``device``.
    """
    import serial

    register_handlers()
    url = printer_url(url)
    _import_own_handler(url)
    if device is None:
        device = _simulated_profile(url)
    settings = device.serial if device is not None else None

    def pick(value, name, default):
        return value if value is not None else getattr(settings, name) if settings else default

    try:
        port = serial.serial_for_url(
            url, do_not_open=True, baudrate=pick(baudrate, "baudrate", 9600),
            bytesize=pick(None, "bytesize", 8), parity=pick(None, "parity", "N"),
            stopbits=pick(None, "stopbits", 1), xonxoff=pick(xonxoff, "xonxoff", False),
            rtscts=pick(rtscts, "rtscts", False), dsrdtr=pick(dsrdtr, "dsrdtr", False),
            timeout=timeout, write_timeout=write_timeout)
        if device is not None and hasattr(port, "profile"):  # sim://: the profile to simulate
            port.profile = device
        port.open()
    except (serial.SerialException, OSError, ValueError) as exc:
        raise FoldfabError(f"cannot open port {url}: {exc}; {_advice(url, str(exc))}") from None
    return port


def printer_url(url: str) -> str:
    """``lp://PATH`` for a path to a file that is not a terminal (a USB printer-class device
    such as ``/dev/usb/lp0``: pyserial cannot configure it); anything else unchanged."""
    import os
    import stat

    if "://" in url:
        return url
    try:
        mode = os.stat(url).st_mode
    except OSError:
        return url  # pyserial's error names it
    if stat.S_ISCHR(mode):
        try:
            fd = os.open(url, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        except OSError:
            return url
        try:
            if os.isatty(fd):
                return url
        finally:
            os.close(fd)
    elif stat.S_ISDIR(mode):
        return url
    return "lp://" + os.path.abspath(url)


def _simulated_profile(url: str) -> DeviceProfile | None:
    """The profile a ``sim://NAME`` URL names (None for other URLs)."""
    from urllib.parse import unquote, urlsplit

    from foldfab.devices import load_device

    parts = urlsplit(url)
    name = unquote(parts.netloc + parts.path)
    if parts.scheme != "sim" or not name:
        return None
    try:
        return load_device(name)
    except FoldfabError as exc:
        raise FoldfabError(f"cannot open port {url}: {exc}") from None


def _import_own_handler(url: str) -> None:
    """Import foldfab's handler for ``url``'s scheme, if there is one, so its errors show."""
    if "://" not in url:
        return
    scheme = url.split("://", 1)[0].lower()
    module = f"{HANDLER_PACKAGE}.protocol_{scheme}"
    try:
        importlib.import_module(module)
    except ImportError as exc:
        if isinstance(exc, ModuleNotFoundError) and exc.name == module:
            return  # not one of foldfab's: pyserial's own, or unknown
        raise FoldfabError(f"cannot open port {url}: the {scheme}:// handler ({module}) "
                           f"cannot be imported: {exc}; reinstall foldfab or fix the "
                           "missing dependency") from exc


def _advice(url: str, message: str) -> str:
    if "protocol" in message and "not known" in message:
        return ("use a device path (/dev/ttyUSB0, COM3) or a URL pyserial knows: socket://, "
                "rfc2217://, spy://, loop://, or foldfab's sim://DEVICE")
    if url.startswith("usb:"):
        return "see foldfab ports for the USB cutters foldfab sees"
    if url.startswith("lp:"):
        return ("check that the cutter is connected and switched on (ls /dev/usb/ /dev/usblp*, "
                "foldfab ports) and that you may use it (group lp: sudo usermod -aG lp $USER)")
    if url.startswith("sim:"):
        return "fix the URL: sim://DEVICE?option=value&... (see foldfab.sim.options)"
    if "://" in url:
        return "check the address and that the server is running and reachable"
    return ("check that the plotter is connected and switched on, the path (ls /dev/serial/by-id/), "
            "that you may use it (group dialout), and that no other program has it open")
