"""The simulated GRBL in laser mode: $30/$31/$32, M3/M4/M5 and S, the beam off on G0 moves
and after M5, M2 and a reset, power changes that do (``$32=0``) or do not stop motion, and the
power of each recorded stroke."""

from __future__ import annotations

from dataclasses import replace
from urllib.parse import urlencode

import numpy as np
import pytest

from foldfab.design import load_design
from foldfab.devices import load_device
from foldfab.fabricate import fabricate
from foldfab.plotting.transport import open_port, register_handlers
from foldfab.programs.interpret import interpret
from helpers import ROOT
from helpers.plans import spec

BANNER_END = b"help]\r\n"


@pytest.fixture(scope="module")
def laser():
    register_handlers()
    return load_device("grbl-laser")


def port_to(device, **options):
    """A sim:// port in instant time, its banner read."""
    port = open_port(f"sim://?{urlencode({'time': 'instant', **options})}", device, timeout=30.0)
    assert port.read_until(BANNER_END).endswith(BANNER_END)
    return port


def send(port, text: str) -> list[bytes]:
    """The lines by character counting (at most 127 bytes unanswered); every reply and message."""
    replies: list[bytes] = []
    pending: list[int] = []

    def answer() -> None:
        reply = port.read_until(b"\r\n")
        assert reply.endswith(b"\r\n"), f"no answer (got {reply!r})"
        replies.append(reply.strip())
        if reply.startswith((b"ok", b"error")):
            pending.pop(0)

    for line in text.splitlines():
        data = line.encode() + b"\n"
        while pending and sum(pending) + len(data) > 127:
            answer()
        port.write(data)
        pending.append(len(data))
    while pending:
        answer()
    return replies


def settings_of(port) -> dict[int, str]:
    replies = send(port, "$$")
    assert replies[-1] == b"ok"
    return {int(r[1:r.index(b"=")]): r[r.index(b"=") + 1:].decode() for r in replies[:-1]}


def test_settings_list_30_31_32(laser):
    assert {k: v for k, v in settings_of(port_to(laser)).items() if k in (30, 31, 32)} == \
        {30: "1000", 31: "0", 32: "1"}
    assert settings_of(port_to(laser, laser_mode=0))[32] == "0"
    assert settings_of(port_to(load_device("grbl")))[32] == "0"


def test_the_beam_burns_on_g1_only_with_its_power_and_is_off_after_m5_m2_and_a_reset(laser):
    port = port_to(laser)
    sim = port.simulator
    assert sim.beam is None
    assert send(port, "G21 G90\nM4 S0\nG0 X10 Y10\nG1 X20 F600 S250\nX30 S500\nG0 X40\nG1 X50") == [b"ok"] * 7
    assert sim.beam == "M4"
    assert send(port, "M5") == [b"ok"]
    sim.run_until_idle()
    assert sim.beam is None
    assert [(s.power, s.points[:, 0].round(3).tolist()) for s in sim.strokes] == \
        [(0.25, [10, 20]), (0.5, [20, 30]), (0.5, [40, 50])]
    send(port, "M3 S100\nG1 X60")
    assert sim.beam == "M3" and sim.strokes[-1].power == 0.1
    send(port, "M2")
    assert sim.beam is None
    send(port, "M4 S300\nG1 X70")
    port.write(b"\x18")
    port.read_until(BANNER_END)
    assert sim.beam is None


def test_without_laser_mode_rapids_burn_too(laser):
    port = port_to(laser, laser_mode=0)
    send(port, "G21 G90\nM4 S0\nG0 X10\nG1 X20 F600 S250\nG0 X40\nM5")
    port.simulator.run_until_idle()
    assert [(s.power, s.points[:, 0].round(3).tolist()) for s in port.simulator.strokes] == \
        [(0.25, [10, 20, 40])]


def straight_run_time(device, laser_mode: int) -> float:
    """Seconds of motion for one straight line whose power changes at every millimetre."""
    port = port_to(device, laser_mode=laser_mode, planner=64)
    lines = [f"G1 X{x} S{100 + x}" for x in range(1, 40)]
    send(port, "G21 G90\nM4 S0\nG1 X0 Y0 F6000\n" + "\n".join(lines) + "\nM5")
    port.simulator.run_until_idle()
    assert port.simulator.stats.bytes_lost == 0
    return port.simulator.stats.busy_time


def test_power_changes_stop_motion_only_without_laser_mode(laser):
    """$32=1: the head runs through S changes on moves at speed; $32=0: it stops at every one."""
    flowing, stopping = straight_run_time(laser, 1), straight_run_time(laser, 0)
    assert flowing < 0.5 * stopping


def test_the_simulator_records_each_strokes_power(laser):
    design = load_design(ROOT / "jobs" / "hexagon-fig8a.toml")
    fab = fabricate(design, laser, spec(strategy="perforate"))
    port = port_to(laser, sheet="297x420")
    replies = send(port, fab.program.text.rstrip("\n").replace("M0", "(no pause)"))
    assert b"error" not in b" ".join(replies)
    port.simulator.run_until_idle()
    drawn = port.simulator.strokes
    want = interpret(fab.program, laser, fab.plan.sheet).strokes
    assert len(drawn) == len(want) > 0
    for got, expected in zip(drawn, want):
        assert got.power == expected.power == pytest.approx(expected.section.tool.power)
        assert np.allclose(got.points, expected.points, atol=1e-9, rtol=0)
    assert {round(s.power, 6) for s in drawn} == {0.6}  # perforation dashes and outline cut alike
    assert port.simulator.beam is None


def test_recorded_laser_strokes_are_named_by_the_layer_of_their_power(laser):
    from foldfab.sim.record import layer_named, stroke_dict

    design = load_design(ROOT / "jobs" / "hexagon-fig8a.toml")
    fab = fabricate(design, laser, spec())
    strokes = interpret(fab.program, laser, fab.plan.sheet).strokes
    named = layer_named([replace(s, section=None) for s in strokes], laser)
    assert [s.section.name for s in named] == \
        ["cut" if s.section.name == "cut" else "valley+mountain" for s in strokes]
    assert stroke_dict(strokes[0])["power"] == 0.15
