"""The ``lp://`` transport: USB printer-class device files (``/dev/usb/lp0``) as ports, on a
simulated printer device (a raw pty served by :mod:`foldfab.sim.printer`)."""

from __future__ import annotations

import os
import pty
import threading

import pytest

from foldfab.design import load_design
from foldfab.devices import load_device
from foldfab.fabricate import fabricate
from foldfab.fabrication.spec import job_spec
from foldfab.job import load_job
from foldfab.programs.interpret import interpret
from foldfab.errors import FoldfabError
from foldfab.plotting.transport import open_port, printer_url
from foldfab.plotting.urlhandler import protocol_lp
from foldfab.sim import create_simulator, parse_options
from foldfab.sim.printer import printer_thread
from helpers import HEXAGON
from helpers.resumes import VASE
from helpers.streams import fabricated, same_strokes
from helpers.usbfaults import FAULTS, check_stop, stop_and_resume

ROLAND = "roland-gx24"


def served(options: str = "time=instant", paper_out_after=None, device=ROLAND):
    """A simulated device served as a printer device file: (path, link, simulator, close)."""
    sim = create_simulator(load_device(device), parse_options(
        [tuple(pair.split("=", 1)) for pair in f"sheet=A3&{options}".split("&")]))
    path, link, stop, thread = printer_thread(sim, paper_out_after)

    def close():
        stop.set()
        thread.join(10)
    return path, link, sim, close


def opened(options, paper_out_after, write_timeout=2.0, device=ROLAND):
    path, _, sim, close = served(options, paper_out_after, device)
    port = open_port(f"lp://{path}", load_device(device), write_timeout=write_timeout)

    def close_all():
        port.close()
        close()
    return port, sim, close_all


def test_a_path_that_is_not_a_terminal_opens_as_a_printer_device(tmp_path):
    """The issue: pyserial configures every path as a terminal and fails on /dev/usb/lp0 with
    "Inappropriate ioctl for device".  A FIFO stands in for it: it is no terminal, and opened
    read-write it hands back what was written."""
    fifo = tmp_path / "lp0"
    os.mkfifo(fifo)
    assert printer_url(str(fifo)) == f"lp://{fifo}"
    port = open_port(str(fifo), load_device(ROLAND), timeout=1.0)
    try:
        assert isinstance(port, protocol_lp.Serial)
        assert port.write(b"IN;PU0,0;") == 9
        assert port.read(9) == b"IN;PU0,0;"
        assert port.in_waiting == 0
        assert port.read(1) == b""  # the timeout, not a hang
    finally:
        port.close()


def test_a_terminal_stays_a_serial_port():
    master, slave = pty.openpty()
    try:
        assert printer_url(os.ttyname(slave)) == os.ttyname(slave)
        assert printer_url("/nonexistent/ttyUSB9") == "/nonexistent/ttyUSB9"
        assert printer_url("socket://localhost:9") == "socket://localhost:9"
    finally:
        os.close(master)
        os.close(slave)


def test_a_missing_device_says_what_to_do():
    with pytest.raises(FoldfabError, match=r"cannot open port lp:///nonexistent/lp0: .*No such file.*"
                                           r"foldfab ports.*group lp"):
        open_port("lp:///nonexistent/lp0", load_device(ROLAND))


def test_roland_plots_the_whole_job_through_its_printer_device(capsys):
    """The issue's "done when": foldfab plot ... --device roland-gx24 --port <its lp path>."""
    from foldfab.cli import main

    path, _, sim, close = served()
    try:
        assert main(["plot", str(HEXAGON), "--device", ROLAND, "--port", f"lp://{path}", "--yes"]) == 0
    finally:
        close()
    assert "done" in capsys.readouterr().out
    device = load_device(ROLAND)
    program = fabricate(load_design(HEXAGON), device, job_spec(load_job(HEXAGON))).program
    assert same_strokes(sim.strokes, interpret(program, device, sim.sheet).strokes)
    assert sim.stats.bytes_lost == 0 and sim.machine.stroke is None


def test_writes_wait_while_the_device_is_busy_and_nothing_is_lost():
    """A device that stops taking data (its buffer full, frozen) blocks the writer; once it
    runs again every byte arrives."""
    path, link, sim, close = served("time=instant&stall=5&stall_at=10&buffer=64")
    port = open_port(f"lp://{path}", load_device(ROLAND), write_timeout=30, timeout=30)
    try:
        data = b"IN;PU0,0;" + b"PD10,10;PU0,0;" * 800 + b"OE;"
        assert port.write(data) == len(data)
        assert port.read(2) == b"0\r"  # answered once everything before it is executed, without error
        assert sim.stats.bytes_received == len(data)
        assert sim.stats.bytes_lost == 0 and sim.stats.stalled_time == pytest.approx(5)
    finally:
        port.close()
        close()


@pytest.fixture
def hung():
    """A port to a device that takes 10 bytes and then nothing (real time: it never recovers)."""
    ports = []

    def open_hung(write_timeout):
        path, _, _, close = served("time=real&stall=1e6&stall_at=10&buffer=64")
        ports.append((open_port(f"lp://{path}", load_device(ROLAND), write_timeout=write_timeout), close))
        return ports[-1][0]
    yield open_hung
    for port, close in ports:
        port.close()
        close()


def test_a_device_that_takes_nothing_is_a_clear_stall(hung):
    port = hung(0.5)
    with pytest.raises(OSError, match=r"took no data for 0.5 s after \d+ of \d+ bytes \(busy"):
        port.write(b"PD1,1;" * (200000 // 6) + b"PU;PU")


def test_cancel_write_stops_a_blocked_write(hung):
    port = hung(60)
    threading.Timer(0.3, port.cancel_write).start()
    assert port.write(b"PD1,1;" * 100000) < 600000


@pytest.mark.parametrize("fault", [fault for fault in FAULTS if fault != "tray-empty"])  # GP-GL's own
def test_fault_stops_safely_and_the_resume_completes_the_drawing(fault):
    device = load_device(ROLAND)
    fab = fabricated(VASE, ROLAND)
    check_stop(fault, *stop_and_resume(device, fab, fault, opened))


@pytest.mark.parametrize("fault", ["cancel", "unplug", "tray-empty"])
def test_the_cameo_through_its_printer_device_stops_safely_and_the_resume_completes_the_drawing(fault):
    """A Silhouette presents a printer-class interface (usblp takes it): the fault matrix on the
    Cameo 4 through lp://, its own tray-empty status among the faults."""
    cameo = "silhouette-cameo-4"
    fab = fabricated(VASE, cameo)
    check_stop(fault, *stop_and_resume(load_device(cameo), fab, fault,
                                       lambda options, paper_out: opened(options, paper_out, device=cameo)))
