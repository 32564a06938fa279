"""open_port: profile settings and overrides, every kind of port, errors that say what to do,
and the real error of a broken URL handler instead of pyserial's "protocol not known"."""

from __future__ import annotations

import socket
import sys
import threading

import pytest
import serial

from foldfab.devices import load_device
from foldfab.errors import FoldfabError
from foldfab.sim import SimOptions, create_simulator
from foldfab.sim.pty import serve_pty
from foldfab.plotting.transport import HANDLER_PACKAGE, open_port


def test_profile_settings_and_overrides():
    graphtec = load_device("graphtec-ce6000")
    port = open_port("sim://", graphtec)  # no name: the profile's simulator
    assert port.simulator.device is graphtec
    assert (port.baudrate, port.bytesize, port.parity, port.stopbits) == (9600, 8, "N", 1)
    assert port.rtscts and not port.xonxoff and port.timeout == 1.0
    port = open_port("sim://graphtec-ce6000?time=instant", graphtec, baudrate=19200, rtscts=False,
                     xonxoff=True, timeout=0.25, write_timeout=3)
    assert (port.baudrate, port.rtscts, port.xonxoff, port.timeout, port.write_timeout) == \
        (19200, False, True, 0.25, 3)
    assert port.simulator.byte_time == pytest.approx(10 / 19200)  # the wire runs at the port's rate
    grbl = open_port("sim://grbl?time=instant")  # a named simulator brings its profile's settings
    assert grbl.baudrate == 115200 and grbl.read_until(b"help]\r\n").endswith(b"help]\r\n")
    assert HANDLER_PACKAGE in serial.protocol_handler_packages
    loop = open_port("loop://")  # no profile: pyserial's defaults
    assert (loop.baudrate, loop.rtscts, loop.xonxoff) == (9600, False, False)
    loop.write(b"IN;")
    assert loop.read(3) == b"IN;"


def test_errors_name_the_port_and_what_to_do():
    grbl = load_device("grbl")
    cases = [
        ("/dev/ttyNOPE-foldfab", "group dialout"),
        ("bogus://x", "protocol 'bogus' not known; use a device path"),
        ("sim://grbl?noise=2", "noise='2': expected a probability"),
        ("sim://nope", "unknown device 'nope'"),
        ("socket://127.0.0.1:1", "check the address and that the server is running"),
    ]
    for url, hint in cases:
        with pytest.raises(FoldfabError, match="cannot open port") as info:
            open_port(url, grbl)
        assert url in str(info.value) and hint in str(info.value)


def test_a_broken_handler_shows_its_real_import_error(monkeypatch):
    """pyserial swallows an ImportError inside a handler; open_port must not."""
    monkeypatch.delitem(sys.modules, f"{HANDLER_PACKAGE}.protocol_sim")
    monkeypatch.setitem(sys.modules, "foldfab.sim.clock", None)  # a dependency fails to import
    with pytest.raises(ValueError, match="protocol 'sim' not known"):
        serial.serial_for_url("sim://grbl")  # all pyserial can say
    with pytest.raises(FoldfabError, match=r"handler \(foldfab.plotting.urlhandler.protocol_sim\) cannot be "
                                           r"imported: import of foldfab.sim.clock halted"):
        open_port("sim://grbl")


def test_socket_urls():
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(1)

    def answer():
        conn, _ = server.accept()
        with conn:
            assert conn.recv(3) == b"\x1b.B"
            conn.sendall(b"1024\r")

    thread = threading.Thread(target=answer)
    thread.start()
    port = open_port(f"socket://127.0.0.1:{server.getsockname()[1]}", load_device("hp7475a"))
    port.write(b"\x1b.B")
    assert port.read_until(b"\r") == b"1024\r"
    port.close()
    thread.join(5)
    server.close()


def test_device_paths_and_spy_urls_on_a_pty(tmp_path):
    device = load_device("hp7475a")
    sim = create_simulator(device, SimOptions(time="fast", speedup=100))
    stop, ready, box = threading.Event(), threading.Event(), {}
    thread = threading.Thread(target=serve_pty, args=(sim, lambda p: (box.update(path=p), ready.set()),
                                                      stop))
    thread.start()
    try:
        assert ready.wait(5)
        port = open_port(box["path"], device, write_timeout=5)
        port.write(b"\x1b.L")
        assert port.read_until(b"\r") == b"1024\r"
        port.close()
        log = tmp_path / "spy.txt"
        spied = open_port(f"spy://{box['path']}?file={log}", device, write_timeout=5)
        spied.write(b"IN;OS;")
        assert spied.read_until(b"\r") == b"24\r"
        spied.close()
        assert "IN;OS;" in log.read_text()
    finally:
        stop.set()
        thread.join(5)
