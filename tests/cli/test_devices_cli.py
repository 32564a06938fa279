"""``foldfab devices`` and ``foldfab ports``."""

from __future__ import annotations

from foldfab.cli import main
from foldfab.plotting.ports import find_ports
from foldfab.plotting.urlhandler import protocol_usb
from foldfab.sim.usb import SimulatedUsbBackend, SimulatedUsbDevice
from helpers import ROOT


def test_devices_lists_the_built_in_and_the_users_profiles(tmp_path, monkeypatch, capsys):
    folder = tmp_path / "foldfab" / "devices"
    folder.mkdir(parents=True)
    text = (ROOT / "devices" / "roland-gx24.toml").read_text()
    (folder / "my-cutter.toml").write_text(text.replace('name = "roland-gx24"', 'name = "my-cutter"')
                                           .replace('port = "/dev/usb/lp0"', 'port = "/dev/usb/lp1"'))
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path))
    assert main(["devices"]) == 0
    lines = {line.split()[0]: line for line in capsys.readouterr().out.splitlines()}
    assert lines["my-cutter"].split()[1:3] == ["hpgl", "user"] and "[port /dev/usb/lp1]" in lines["my-cutter"]
    assert lines["hp7475a"].split()[1:3] == ["hpgl", "built-in"] and "HP 7475A" in lines["hp7475a"]
    assert lines["grbl"].split()[1:3] == ["gcode", "built-in"]


def silhouettes(monkeypatch, *products):
    from foldfab.devices import load_device
    from foldfab.sim import create_simulator
    from foldfab.sim.usblink import UsbLink

    sim = create_simulator(load_device("roland-gx24"))
    devices = [SimulatedUsbDevice(UsbLink(sim), 0x0B4D, product, f"S{i}", address=i + 1)
               for i, product in enumerate(products)]
    monkeypatch.setattr(protocol_usb, "BACKEND", SimulatedUsbBackend(devices))


def test_ports_finds_printer_devices_and_usb_cutters_with_the_profiles_that_fit(tmp_path, monkeypatch):
    dev, sys = tmp_path / "dev", tmp_path / "sys"
    (dev / "usb").mkdir(parents=True)
    (dev / "usb" / "lp0").write_bytes(b"")
    (dev / "usblp1").write_bytes(b"")
    ids = sys / "class" / "usbmisc" / "lp0" / "device"
    ids.mkdir(parents=True)
    (ids / "ieee1284_id").write_bytes(b"\x00\x2aMFG:Roland;MDL:GX-24;CLS:PRINTER;" + b"X" * 5000)
    silhouettes(monkeypatch, 0x1137, 0x1121)
    found, notes = find_ports(str(dev), str(sys))
    by_port = {p.port: p for p in found}
    assert by_port["/dev/usb/lp0"].kind == "printer"
    assert by_port["/dev/usb/lp0"].description == "Roland GX-24"
    assert "roland-gx24" in by_port["/dev/usb/lp0"].profiles
    assert by_port["/dev/usblp1"].description == "USB printer device" and not by_port["/dev/usblp1"].profiles
    cameo4 = by_port["usb://0b4d:1137?serial=S0"]
    assert cameo4.kind == "usb" and cameo4.description == "Silhouette Cameo 4"
    assert by_port["usb://0b4d:1121?serial=S1"].description == "Silhouette Cameo" and not notes


def test_ports_command_prints_what_is_connected(monkeypatch, capsys):
    silhouettes(monkeypatch, 0x113A)
    assert main(["ports"]) == 0
    out = capsys.readouterr().out
    assert "usb      usb://0b4d:113a?serial=S0" in out and "Silhouette Portrait 3" in out


def test_ports_without_libusb_says_what_to_install(monkeypatch, capsys):
    import usb.core

    def no_backend(**kwargs):
        raise usb.core.NoBackendError("No backend available")
    monkeypatch.setattr(usb.core, "find", no_backend)
    assert main(["ports"]) == 0
    assert "note: USB cutters: pyusb finds no libusb: install it (Debian: apt-get install libusb-1.0-0)" \
        in capsys.readouterr().out


def test_a_hostile_serial_number_is_printed_tame(monkeypatch, capsys):
    from foldfab.devices import load_device
    from foldfab.sim import create_simulator
    from foldfab.sim.usblink import UsbLink

    serial = "A\x1b[2J\nB&x=1?/" + "9" * 500
    sim = create_simulator(load_device("roland-gx24"))
    monkeypatch.setattr(protocol_usb, "BACKEND", SimulatedUsbBackend(
        [SimulatedUsbDevice(UsbLink(sim), 0x0B4D, 0x1137, serial)]))
    assert main(["ports"]) == 0
    line = next(line for line in capsys.readouterr().out.splitlines() if line.startswith("usb"))
    port = line.split()[1]
    assert port == "usb://0b4d:1137?serial=A[2JBx=1" + "9" * 56
    from foldfab.plotting.transport import open_port

    open_port(port, load_device("roland-gx24")).close()  # the printed URL finds it
