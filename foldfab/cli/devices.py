"""``foldfab devices`` (the device profiles) and ``foldfab ports`` (what is connected)."""

from __future__ import annotations

import argparse


def cmd_devices(args: argparse.Namespace) -> int:
    """List the built-in and the user's profiles with protocol and model."""
    from foldfab.devices import list_devices, load_device
    from foldfab.devices.load import profile_origin
    from foldfab.errors import FoldfabError

    for name in list_devices():
        try:
            device = load_device(name)
        except FoldfabError as exc:
            print(f"{name:24} (broken: {exc})")
            continue
        print(f"{name:24} {device.protocol:6} {profile_origin(device):8} {device.model}" +
              (f"  [port {device.port}]" if device.port else ""))
    return 0


def cmd_ports(args: argparse.Namespace) -> int:
    """List serial ports, USB printer devices and known USB cutters, with the profiles that fit."""
    from foldfab.plotting.ports import find_ports

    found, notes = find_ports()
    for port in found:
        fits = f"  profile: {', '.join(port.profiles)}" if port.profiles else ""
        print(f"{port.kind:8} {port.port:32} {port.description}{fits}")
    if not found:
        print("no serial port, USB printer device or known USB cutter is connected")
    for note in notes:
        print(f"note: {note}")
    return 0


def add_commands(sub) -> None:
    devices = sub.add_parser("devices", help="list the device profiles (built-in and yours)")
    devices.set_defaults(func=cmd_devices)
    ports = sub.add_parser("ports", help="list connected serial ports, USB printer devices and USB cutters")
    ports.set_defaults(func=cmd_ports)
