"""The ``usb://`` transport (pyusb) on simulated cutters behind a pyusb backend
(:class:`foldfab.sim.usb.SimulatedUsbBackend`): the handler's real path runs, find, detach
the kernel driver, claim, bulk transfers, timeouts."""

from __future__ import annotations

import errno

import pytest
import usb.core

from foldfab.design import load_design
from foldfab.devices import load_device
from foldfab.errors import FoldfabError
from foldfab.fabricate import fabricate
from foldfab.fabrication.spec import job_spec
from foldfab.job import load_job
from foldfab.plotting.transport import open_port
from foldfab.plotting.urlhandler import protocol_usb
from foldfab.programs.interpret import interpret
from foldfab.sim import create_simulator, parse_options
from foldfab.sim.usb import SimulatedUsbBackend, SimulatedUsbDevice
from foldfab.sim.usblink import UsbLink
from helpers import HEXAGON
from helpers.resumes import VASE
from helpers.streams import fabricated, same_strokes
from helpers.usbfaults import FAULTS, check_stop, stop_and_resume

ROLAND = "roland-gx24"  # an HP-GL cutter stands in for any protocol: the link carries bytes


def simulated(options="time=instant", paper_out_after=None, device=ROLAND, product=0x1137,
              serial="SIM0001", address=1) -> SimulatedUsbDevice:
    sim = create_simulator(load_device(device), parse_options(
        [tuple(pair.split("=", 1)) for pair in f"sheet=A3&{options}".split("&")]))
    return SimulatedUsbDevice(UsbLink(sim, paper_out_after), 0x0B4D, product, serial, address=address)


@pytest.fixture
def bus(monkeypatch):
    """Put simulated devices on the bus the usb:// handler looks at."""
    def plug(*devices):
        monkeypatch.setattr(protocol_usb, "BACKEND", SimulatedUsbBackend(list(devices)))
        return devices
    return plug


@pytest.mark.parametrize("url, parsed", [
    ("usb://0b4d:1137", (0x0B4D, 0x1137, None)),
    ("usb://0B4D:113a?serial=AB%2012", (0x0B4D, 0x113A, "AB 12")),
    ("usb://silhouette", (0x0B4D, None, None)),
    ("usb://silhouette?serial=X", (0x0B4D, None, "X")),
])
def test_usb_urls(url, parsed):
    assert protocol_usb.parse_usb_url(url) == parsed


@pytest.mark.parametrize("url", ["usb://", "usb://0b4d", "usb://0b4d:", "usb://10000:1", "usb://xyz:1137",
                                 "usb://0b4d:1137?baud=9600", "usb://-1:5", "usb://00000b4d:1137",
                                 "usb://cameo", "usb://0b4d:1137:1"])
def test_bad_usb_urls_say_what_is_expected(url, bus):
    bus()
    with pytest.raises(FoldfabError, match=r"expected usb://"):
        open_port(url)


def test_the_job_is_drawn_whole_through_the_simulated_usb_cutter(bus, capsys):
    """The issue's "done when", on the usb:// path: find, claim, bulk transfers, every stroke."""
    from foldfab.cli import main

    (cutter,) = bus(simulated())
    assert main(["plot", str(HEXAGON), "--device", ROLAND, "--port", "usb://silhouette", "--yes"]) == 0
    assert "done" in capsys.readouterr().out
    device, sim = load_device(ROLAND), cutter.link.sim
    program = fabricate(load_design(HEXAGON), device, job_spec(load_job(HEXAGON))).program
    assert same_strokes(sim.strokes, interpret(program, device, sim.sheet).strokes)
    assert sim.stats.bytes_lost == 0 and sim.machine.stroke is None
    assert not cutter.kernel_driver  # detached from usblp to claim the interface
    assert not cutter.claimed  # released when the port closed


def test_the_serial_number_chooses_among_several(bus):
    first, second = bus(simulated(serial="A1", address=1), simulated(serial="B2", address=2))
    port = open_port("usb://0b4d:1137?serial=B2", load_device(ROLAND), timeout=5)
    try:
        port.write(b"IN;OE;")
        assert port.read(2) == b"0\r"
    finally:
        port.close()
    assert second.link.sim.stats.bytes_received == 6 and first.link.sim.stats.bytes_received == 0


def test_a_missing_device_lists_what_foldfab_sees(bus):
    bus(simulated(product=0x113A, serial="P3"))
    with pytest.raises(FoldfabError, match=r"no USB device 0b4d:1137 is connected \(USB devices foldfab "
                                           r"sees: 0b4d:113a \(Silhouette Portrait 3, serial P3\)\)"):
        open_port("usb://0b4d:1137")
    with pytest.raises(FoldfabError, match=r"no USB device silhouette\?serial=Q is connected"):
        open_port("usb://silhouette?serial=Q")


def test_permission_denied_gives_the_udev_rule(bus, monkeypatch):
    bus(simulated())

    def denied(self, dev_handle, intf):
        raise usb.core.USBError("Access denied (insufficient permissions)", -3, errno.EACCES)
    monkeypatch.setattr(SimulatedUsbBackend, "is_kernel_driver_active", denied)
    with pytest.raises(FoldfabError, match=r"permission denied: .*udev rule.*"
                                           r'SUBSYSTEM=="usb", ATTR\{idVendor\}=="0b4d"'):
        open_port("usb://silhouette")


def test_a_device_that_stops_answering_times_out_reads(bus):
    bus(simulated("time=instant&mute=1"))
    port = open_port("usb://silhouette", load_device(ROLAND), timeout=0.2)
    try:
        port.write(b"IN;OE;")
        assert port.read(2) == b""
        assert port.in_waiting == 0
    finally:
        port.close()


def test_writes_wait_while_the_cutter_is_busy_and_nothing_is_lost(bus):
    (cutter,) = bus(simulated("time=instant&stall=5&stall_at=10&buffer=64"))
    port = open_port("usb://silhouette", load_device(ROLAND), timeout=30, write_timeout=30)
    try:
        data = b"IN;PU0,0;" + b"PD10,10;PU0,0;" * 300 + b"OE;"
        assert port.write(data) == len(data)
        assert port.read(2) == b"0\r"
    finally:
        port.close()
    sim = cutter.link.sim
    assert sim.stats.bytes_received == len(data) and sim.stats.bytes_lost == 0
    assert sim.stats.stalled_time == pytest.approx(5)


@pytest.mark.parametrize("fault", [fault for fault in FAULTS if fault != "tray-empty"])  # GP-GL's own
def test_fault_stops_safely_and_the_resume_completes_the_drawing(fault, monkeypatch):
    def opened(options, paper_out_after):
        cutter = simulated(options, paper_out_after)
        monkeypatch.setattr(protocol_usb, "BACKEND", SimulatedUsbBackend([cutter]))
        port = open_port("usb://0b4d:1137", load_device(ROLAND), write_timeout=2.0)
        return port, cutter.link.sim, port.close

    check_stop(fault, *stop_and_resume(load_device(ROLAND), fabricated(VASE, ROLAND), fault, opened))


def test_an_environment_variable_puts_a_simulated_cutter_on_the_bus(monkeypatch, capsys):
    """FOLDFAB_USB_SIM: a whole plot over usb:// without the cutter, from the command line."""
    from foldfab.cli import main

    monkeypatch.setattr(protocol_usb, "_SIMULATED", {})
    monkeypatch.setenv("FOLDFAB_USB_SIM", "roland-gx24?time=instant&sheet=A3")
    assert main(["plot", str(HEXAGON), "--device", ROLAND, "--port", "usb://silhouette", "--yes"]) == 0
    (backend,) = protocol_usb._SIMULATED.values()
    sim = backend.devices[0].link.sim
    device = load_device(ROLAND)
    program = fabricate(load_design(HEXAGON), device, job_spec(load_job(HEXAGON))).program
    assert same_strokes(sim.strokes, interpret(program, device, sim.sheet).strokes)
    capsys.readouterr()
    monkeypatch.setenv("FOLDFAB_USB_SIM", "no-such-cutter")
    assert main(["plot", str(HEXAGON), "--device", ROLAND, "--port", "usb://silhouette", "--yes"]) == 2
    assert "FOLDFAB_USB_SIM=no-such-cutter: unknown device 'no-such-cutter'" in capsys.readouterr().err


def test_a_simulated_cutter_has_its_profiles_usb_ids(monkeypatch):
    """The ids come from the known cutters' table: a profile named there is found by its id."""
    from foldfab.devices import usb as known
    from foldfab.sim.usb import simulated_cutter

    monkeypatch.setitem(known.KNOWN_CUTTERS, (0x0B4D, 0x113A),
                        known.UsbCutter(0x0B4D, 0x113A, "Silhouette Portrait 3", ROLAND))
    cutter = simulated_cutter(f"{ROLAND}?time=instant")
    assert (cutter.vendor, cutter.product) == (0x0B4D, 0x113A)
    assert (simulated_cutter("grbl").vendor, simulated_cutter("grbl").product) == (0x0B4D, 0x1137)
    with pytest.raises(FoldfabError, match="simulated USB cutter grbl\\?noise=2"):
        simulated_cutter("grbl?noise=2")


def test_the_silhouette_cameo_4_draws_the_whole_job_over_usb(monkeypatch, capsys):
    """Issue 21's "done when": `plot --device silhouette-cameo-4 --port usb://silhouette` on the
    simulated Cameo 4 behind pyusb (GP-GL, status polling, found by its own USB id 0b4d:1137)."""
    from foldfab.cli import main

    cameo = "silhouette-cameo-4"
    monkeypatch.setattr(protocol_usb, "_SIMULATED", {})
    monkeypatch.setenv("FOLDFAB_USB_SIM", f"{cameo}?time=instant")
    assert main(["plot", str(HEXAGON), "--device", cameo, "--port", "usb://silhouette", "--yes"]) == 0
    assert "done" in capsys.readouterr().out
    (backend,) = protocol_usb._SIMULATED.values()
    (found,) = backend.devices
    assert (found.vendor, found.product) == (0x0B4D, 0x1137)
    sim = found.link.sim
    device = load_device(cameo)
    program = fabricate(load_design(HEXAGON), device, job_spec(load_job(HEXAGON))).program
    assert same_strokes(sim.strokes, interpret(program, device, sim.sheet).strokes)
    assert sim.stats.bytes_lost == 0 and sim.machine.stroke is None


@pytest.mark.parametrize("fault", ["cancel", "unplug", "tray-empty"])
def test_the_cameo_over_usb_stops_safely_and_the_resume_completes_the_drawing(fault, monkeypatch):
    """The fault matrix on the Silhouette itself behind pyusb: GP-GL status polling over the bus,
    its tray-empty status among the faults."""
    cameo = "silhouette-cameo-4"

    def opened(options, paper_out_after):
        cutter = simulated(options, paper_out_after, device=cameo)
        monkeypatch.setattr(protocol_usb, "BACKEND", SimulatedUsbBackend([cutter]))
        port = open_port("usb://silhouette", load_device(cameo), write_timeout=2.0)
        return port, cutter.link.sim, port.close

    check_stop(fault, *stop_and_resume(load_device(cameo), fabricated(VASE, cameo), fault, opened))
