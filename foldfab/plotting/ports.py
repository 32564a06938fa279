"""What is connected: serial ports, USB printer-class devices and known USB cutters, each with
the device profiles that fit it (``foldfab ports``).

A profile fits a serial port or printer device whose path is its ``port``, and a USB cutter
whose model foldfab knows (:mod:`foldfab.devices.usb`).  The printer device's IEEE 1284 id
(``MFG:Roland;MDL:GX-24;...``, which ``usblp`` shows in sysfs) names what is on it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

ID_LIMIT = 1024
"""Bytes of a printer's IEEE 1284 id read (it is the device's text: bounded, printable only)."""


@dataclass(frozen=True)
class FoundPort:
    """A connected port: what ``--port`` takes, what it is, the profiles that fit."""

    kind: str
    """``serial``, ``printer`` (USB printer class) or ``usb`` (raw USB cutter)."""
    port: str
    description: str
    profiles: tuple[str, ...]


def profiles_by_port() -> dict[str, list[str]]:
    """Profile names by their ``port`` (profiles that fail to load are left out here)."""
    from foldfab.devices import list_devices, load_device
    from foldfab.errors import FoldfabError

    found: dict[str, list[str]] = {}
    for name in list_devices():
        try:
            port = load_device(name).port
        except FoldfabError:
            continue
        if port:
            found.setdefault(port, []).append(name)
    return found


def find_ports(dev_root: str = "/dev", sys_root: str = "/sys") -> tuple[list[FoundPort], list[str]]:
    """Connected ports, and notes on what could not be looked at (no libusb)."""
    from serial import SerialException
    from serial.tools import list_ports

    from foldfab.devices import list_devices
    from foldfab.devices.usb import usb_cutter
    from foldfab.plotting.urlhandler.protocol_usb import _serial, usb_devices

    by_port, found, notes = profiles_by_port(), [], []
    for info in sorted(list_ports.comports(), key=lambda p: p.device):
        found.append(FoundPort("serial", info.device, info.description or "serial port",
                               tuple(by_port.get(info.device, ()))))
    dev = Path(dev_root)
    for path in sorted([*dev.glob("usb/lp*"), *dev.glob("usblp*")]):
        name = str(Path("/dev") / path.relative_to(dev))
        found.append(FoundPort("printer", name, printer_id(Path(sys_root), path.name) or "USB printer device",
                               tuple(by_port.get(name, ()))))
    try:
        devices = usb_devices()
    except SerialException as exc:
        devices, notes = [], [f"USB cutters: {exc}"]
    names = set(list_devices())
    for usb in devices:
        cutter = usb_cutter(usb.idVendor, usb.idProduct)
        if cutter is None:
            continue
        serial = _serial(usb)
        url = f"usb://{cutter.id}" + (f"?serial={serial}" if serial else "")
        fits = (cutter.profile,) if cutter.profile in names else ()
        found.append(FoundPort("usb", url, cutter.model, fits))
    return found, notes


def printer_id(sys_root: Path, name: str) -> str | None:
    """``Roland GX-24`` from the IEEE 1284 id of printer device ``name`` (lp0), if sysfs has one."""
    path = sys_root / "class" / "usbmisc" / name / "device" / "ieee1284_id"
    try:
        with open(path, "rb") as file:
            text = file.read(ID_LIMIT).decode("ascii", "replace")
    except OSError:
        return None
    fields = dict(re.findall(r"(MFG|MANUFACTURER|MDL|MODEL):([ -~]{1,64}?)(?:;|$)", text))
    maker = fields.get("MFG") or fields.get("MANUFACTURER")
    model = fields.get("MDL") or fields.get("MODEL")
    words = [w.strip() for w in (maker, model) if w and w.strip()]
    return " ".join(words) or None
