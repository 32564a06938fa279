"""The simulated GP-GL cutter: status answers as the firmware gives them, initialise, the tray-empty
fault, and ``foldfab sim silhouette-cameo-4`` on a pseudo-terminal."""

from __future__ import annotations

import re
import signal
import subprocess
import sys

import pytest
import serial

from foldfab.devices import load_device
from foldfab.programs.interpret import interpret
from foldfab.sim import SimOptions, create_simulator, parse_options
from helpers import HEXAGON, ROOT
from helpers.streams import fabricated, same_strokes, send_status, sim_port, strokes_of

CAMEO = "silhouette-cameo-4"
LINE = "\x1b\x04J1\x03FX10,1\x03!10,1\x03M0,0\x03D0,0\x03D2000,0\x03M0,0\x03"  # 100 mm at 100 mm/s


def status(port) -> bytes:
    port.write(b"\x1b\x05")
    return port.read_until(b"\x03")


def test_status_is_ready_moving_then_ready_again():
    device = load_device(CAMEO)
    port = sim_port(device, "time=instant")
    assert status(port) == b"0\x03"  # before anything: ready (the firmware answers before ESC 0x04 too)
    port.write(LINE.encode())
    assert status(port) == b"1\x03"  # answered at once, ahead of the buffered commands
    port.simulator.run_until_idle()
    assert status(port) == b"0\x03"
    assert same_strokes(port.simulator.strokes, interpret(LINE, device).strokes)


def test_initialise_discards_what_the_buffer_holds_and_lifts_the_tool():
    device = load_device(CAMEO)
    port = sim_port(device, "time=instant")
    port.write(b"J1\x03M0,0\x03D0,0\x03D2000,0\x03D2000,2000\x03D0,2000\x03")
    port.write(b"\x1b\x04")
    port.simulator.run_until_idle()
    sim = port.simulator
    assert sim.machine.stroke is None and len(sim.strokes) == 1
    assert len(sim.strokes[0].points) < 5 and not sim.rx and not sim.commands


def test_a_cutter_without_a_sheet_answers_tray_empty_and_draws_nothing():
    device = load_device(CAMEO)
    port = sim_port(device, "time=instant&unload_at=0")
    assert status(port) == b"2\x03"
    port.write(LINE.encode())
    port.simulator.run_until_idle()
    assert port.simulator.strokes == [] and status(port) == b"2\x03"


def test_the_sheet_coming_out_stops_the_cutter_with_the_tool_up():
    device = load_device(CAMEO)
    fab = fabricated(str(HEXAGON), CAMEO)
    port = sim_port(device, "time=instant&unload_at=500")
    sim = port.simulator
    port.write(fab.program.encode()[:400])
    sim.run_until_idle()
    drawn = len(sim.strokes)
    port.write(fab.program.encode()[400:1000])
    sim.run_until_idle()
    assert status(port) == b"2\x03" and sim.machine.stroke is None and "tray empty" in sim.stats.errors
    assert 0 < drawn <= len(sim.strokes) <= drawn + 1 < len(strokes_of(fab.program, device))


def test_a_stalled_cutter_answers_the_status_only_when_it_goes_on():
    device = load_device(CAMEO)
    port = sim_port(device, "time=instant&stall=5&stall_at=10")
    port.timeout = 1.0
    port.write(LINE.encode())
    port.write(b"\x1b\x05")
    assert port.read_until(b"\x03") == b""  # nothing within a second of the five
    port.timeout = 10.0
    assert port.read_until(b"\x03") in (b"0\x03", b"1\x03")
    assert port.simulator.stats.stalled_time == pytest.approx(5)


def test_unload_at_is_a_checked_fault_option_spent_by_a_power_cycle():
    assert parse_options([("unload_at", "300")]).unload_at == 300
    with pytest.raises(Exception, match="unload_at='x': expected a byte count"):
        parse_options([("unload_at", "x")])
    assert SimOptions(unload_at=3).switched_on().unload_at is None


def test_the_reference_sender_loses_nothing_on_every_gpgl_profile():
    for name in ("silhouette-cameo-4", "silhouette-portrait-3", "graphtec-ce6000-gpgl"):
        device = load_device(name)
        sim = create_simulator(device, SimOptions(time="instant"))
        assert sim.status() == "0"
        port = sim_port(device, "time=instant")
        fab = fabricated(str(HEXAGON), name)
        send_status(port, fab.program.encode())
        assert port.simulator.stats.bytes_lost == 0
        assert same_strokes(port.simulator.strokes, strokes_of(fab.program, device))


def test_foldfab_sim_serves_the_cameo_on_a_pseudo_terminal():
    device = load_device(CAMEO)
    fab = fabricated(str(HEXAGON), CAMEO)
    proc = subprocess.Popen([sys.executable, "-m", "foldfab", "sim", CAMEO, "--time", "fast", "-o", "sheet=A3",
                             "-o", "speedup=200"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        port = serial.Serial(proc.stdout.readline().strip(), 115200, timeout=10)
        send_status(port, fab.program.encode())
        port.close()
        served = proc.stdout.readline()
    finally:
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    length = sum(s.length for s in strokes_of(fab.program, device))
    assert re.fullmatch(rf"job 1 +received \d+ bytes, drew {length:.1f} mm in [\d.]+ s\n", served), served
    assert "0 lost" in out
