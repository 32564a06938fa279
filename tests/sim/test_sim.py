"""Simulated plotters: senders that respect the handshake lose nothing, naive ones lose bytes;
recorded strokes equal the interpreter's; GRBL and HP-GL protocol details; every fault option;
the virtual clock; and the same over a real pseudo-terminal."""

from __future__ import annotations

import json
import math
import re
import signal
import subprocess
import sys
import threading
import time
from collections import deque
from dataclasses import replace
from urllib.parse import urlencode

import numpy as np
import pytest
import serial
from hypothesis import given, settings
from hypothesis import strategies as st

from foldfab.design import load_design
from foldfab.devices import load_device
from foldfab.errors import FoldfabError
from foldfab.programs.estimate import estimate, move_limits, move_times, polyline_runs, travel_times
from foldfab.fabricate import fabricate
from foldfab.programs.interpret import interpret
from foldfab.programs.read_hpgl import HPGLMachine, HPGLTokenizer
from foldfab.sim import SimOptions, create_simulator, parse_options
from foldfab.sim.pty import serve_pty
from foldfab.plotting.transport import open_port, register_handlers
from helpers import DEVICES, ROOT
from helpers.plans import spec
from helpers.streams import send_status

JOB = ROOT / "jobs" / "hexagon-fig8a.toml"
SHEET = "297x420"  # the A3 sheet of spec()
LONG = {"layers": {"valley": {"passes": 8}, "mountain": {"passes": 8}, "cut": {"passes": 4}}}
BANNER = b"\r\nGrbl 1.1h ['$' for help]\r\n"


_FABS: dict = {}


def job(device_name: str, kind: str = "plain"):
    """(device, fabrication) of the hexagon: "plain", "long" (many passes) or "two-sided"."""
    if (device_name, kind) not in _FABS:
        extra = {"plain": {}, "long": LONG, "two-sided": {"strategy": "two-sided"}}[kind]
        device = load_device(device_name)
        _FABS[device_name, kind] = device, fabricate(load_design(JOB), device, spec(**extra))
    return _FABS[device_name, kind]


def sim_port(device, timeout=1.0, **options):
    """A sim:// port in instant time on the A3 sheet; ``xonxoff``/``rtscts`` (off) go to the port."""
    port_args = {key: options.pop(key, False) for key in ("xonxoff", "rtscts")}
    query = urlencode({"time": "instant", "sheet": SHEET, **options})
    return open_port(f"sim://?{query}", device, timeout=timeout, **port_args)


def wanted(device, fab):
    return interpret(fab.program, device, fab.plan.sheet)


def same_strokes(got, want) -> bool:
    return len(got) == len(want) and all(
        a.points.shape == b.points.shape and np.allclose(a.points, b.points, atol=1e-9)
        and (a.pen, a.force, a.speed, a.pen_down) == (b.pen, b.force, b.speed, b.pen_down)
        for a, b in zip(got, want))


# --- reference senders ------------------------------------------------------------------


def pause(port, seconds: float) -> None:
    """Let time pass the way a sender does: a read that expects nothing."""
    timeout, port.timeout = port.timeout, seconds
    assert port.read(1) == b""
    port.timeout = timeout


def send_escb(port, data: bytes, chunk: int = 128) -> None:
    """HP-GL pacing by ESC.B: send no more than the plotter says it has room for."""
    sent = 0
    while sent < len(data):
        port.write(b"\x1b.B")
        free = int(port.read_until(b"\r"))
        if free < min(chunk, len(data) - sent):
            pause(port, 0.1)
            continue
        port.write(data[sent:sent + free])
        sent += free


class Grbl:
    """A GRBL character-counting sender (at most 127 bytes unacknowledged)."""

    def __init__(self, port):
        self.port = port
        self.pending: deque[int] = deque()
        self.replies: list[bytes] = []
        self.statuses: list[bytes] = []
        self.messages: list[bytes] = []

    def line(self) -> bytes:
        reply = self.port.read_until(b"\r\n")
        assert reply.endswith(b"\r\n"), f"GRBL did not answer (got {reply!r})"
        reply = reply.strip()
        if reply == b"ok" or reply.startswith(b"error"):
            self.pending.popleft()
            self.replies.append(reply)
        elif reply.startswith(b"<"):
            self.statuses.append(reply)
        elif reply:
            self.messages.append(reply)
        return reply

    def send(self, text: str) -> None:
        for line in text.splitlines(keepends=True):
            data = line.encode()
            while self.pending and sum(self.pending) + len(data) > 127:
                self.line()
            self.port.write(data)
            self.pending.append(len(data))
            if line.strip() == "M0":  # the operator resumes once the machine holds
                self.wait_state(b"<Hold:0")
                self.port.write(b"~")
        self.finish()

    def finish(self) -> None:
        while self.pending:
            self.line()

    def status(self) -> bytes:
        self.port.write(b"?")
        count = len(self.statuses)
        while len(self.statuses) == count:
            self.line()
        return self.statuses[-1]

    def wait_state(self, prefix: bytes) -> None:
        while not self.status().startswith(prefix):
            pause(self.port, 0.2)


def careful_send(port, device, data: bytes) -> None:
    """The reference sender for each profile's handshake (the port obeys XON/XOFF, RTS/CTS)."""
    flow = port.simulator.flow
    if flow == "grbl":
        assert port.read_until(b"help]\r\n") == BANNER
        Grbl(port).send(data.decode())
    elif flow in ("escb", "none"):
        send_escb(port, data)
    elif flow == "status":
        send_status(port, data)
    else:
        port.write(data)
    port.simulator.run_until_idle()


def careful_port(device, timeout=60.0, **options):
    """A port whose driver obeys the device's XON/XOFF or RTS/CTS; replies may take long."""
    flow = options.get("flow") or device.buffer.flow_control
    return sim_port(device, timeout, xonxoff=flow == "xonxoff", rtscts=flow == "rtscts", **options)


# --- the tokenizer's coordinate pairs -------------------------------------------------


def test_tokenizer_splits_coordinate_pairs_as_they_complete():
    data = b"IN;PD1,2,3,4,5;PU-1-2 3 4;SP1;PA"
    tok = HPGLTokenizer(split_coordinates=True)
    pieces = []
    for i in range(len(data)):  # byte by byte: each pair as soon as the next byte follows it
        pieces += [(c.name, c.params, c.offset, c.part) for c in tok.feed(data[i:i + 1])]
        if i == data.index(b"3,4") - 1:  # "PD1,2," has arrived
            assert pieces[-1] == ("PD", (1.0, 2.0), 3, 0) and tok.committed == 8
    pieces += [(c.name, c.params, c.offset, c.part) for c in tok.close()]
    assert pieces == [("IN", (), 0, 0), ("PD", (1.0, 2.0), 3, 0), ("PD", (3.0, 4.0), 8, 1),
                      ("PD", (5.0,), 12, 2), ("PU", (-1.0, -2.0), 15, 0), ("PU", (3.0, 4.0), 21, 1),
                      ("SP", (1.0,), 26, 0), ("PA", (), 30, 0)]
    assert tok.committed == tok.offset == len(data)
    # the pieces mean what the whole commands mean
    device = load_device("hp7475a")
    text = "IN;SP1;PA100,100;PD200,100,200,200,100,200;PR10,10,-5,0;PU;"
    whole, split = HPGLMachine(device, device.frame(device.sheet), None), \
        HPGLMachine(device, device.frame(device.sheet), None)
    for command in HPGLTokenizer().feed(text.encode()):
        whole.execute(command)
    for command in HPGLTokenizer(split_coordinates=True).feed(text.encode()):
        split.execute(command)
    assert same_strokes(split.finish().strokes, whole.finish().strokes)


# --- losing bytes, and not -----------------------------------------------------------


@pytest.mark.parametrize("device_name", DEVICES)
def test_naive_sender_loses_bytes_careful_sender_does_not(device_name):
    device, fab = job(device_name, "long")
    data = fab.program.encode()
    assert len(data) > 3 * device.buffer.size
    naive = sim_port(device)  # no handshake: one write, at wire speed
    naive.write(data)
    naive.simulator.run_until_idle()
    stats = naive.simulator.stats
    assert stats.bytes_lost > 0 and stats.overruns > 0
    assert not same_strokes(naive.simulator.strokes, wanted(device, fab).strokes)

    careful = careful_port(device)
    careful_send(careful, device, data)
    stats = careful.simulator.stats
    assert stats.bytes_lost == 0 and stats.errors == []
    assert same_strokes(careful.simulator.strokes, wanted(device, fab).strokes)


def test_xonxoff_pacing_by_the_port_and_by_hand():
    device, fab = job("roland-gx24", "long")
    data = fab.program.encode()
    by_driver = careful_port(device, flow="xonxoff")  # the port obeys XON/XOFF and eats them
    by_driver.write(data)
    by_driver.simulator.run_until_idle()
    stats = by_driver.simulator.stats
    assert stats.bytes_lost == 0 and stats.xoff_sent > 0 and stats.xon_sent == stats.xoff_sent
    assert by_driver.in_waiting == 0
    assert same_strokes(by_driver.simulator.strokes, wanted(device, fab).strokes)

    by_hand = sim_port(device, flow="xonxoff")  # the sender reads XOFF/XON itself
    sent, stopped = 0, False
    while sent < len(data):
        for byte in by_hand.read(by_hand.in_waiting):
            stopped = {0x13: True, 0x11: False}.get(byte, stopped)
        if stopped:  # wait for XON
            stopped = by_hand.read(1) != b"\x11"
            continue
        by_hand.write(data[sent:sent + 16])  # the plotter's headroom is larger than this
        sent += 16
    by_hand.simulator.run_until_idle()
    assert by_hand.simulator.stats.bytes_lost == 0
    assert same_strokes(by_hand.simulator.strokes, wanted(device, fab).strokes)


def test_cts_reflects_buffer_space():
    device, fab = job("graphtec-ce6000", "long")
    port = sim_port(device)  # rtscts off at the port: the sender watches CTS itself
    data, sent, lows = fab.program.encode(), 0, 0
    while sent < len(data):
        if not port.cts:
            lows += 1
            continue  # each look at a low CTS lets a moment pass
        port.write(data[sent:sent + 32])
        sent += 32
    port.simulator.run_until_idle()
    assert lows > 0 and port.cts
    assert port.simulator.stats.bytes_lost == 0
    assert same_strokes(port.simulator.strokes, wanted(device, fab).strokes)


# --- strokes and time ----------------------------------------------------------------


@pytest.mark.parametrize("device_name", DEVICES)
def test_recorded_strokes_equal_the_interpretation(device_name, tmp_path):
    device, fab = job(device_name)
    port = careful_port(device)
    careful_send(port, device, fab.program.encode())
    sim, run = port.simulator, wanted(device, fab)
    assert same_strokes(sim.strokes, run.strokes)
    stats = sim.stats
    assert stats.bytes_lost == 0 and stats.errors == []
    assert stats.busy_time == pytest.approx(estimate(run, device).total, rel=1e-9)
    assert stats.plot_time >= stats.busy_time
    sim.write_svg(tmp_path / "drawn.svg")
    assert (tmp_path / "drawn.svg").read_text().count("<path") >= 1
    record = json.loads(sim.to_json())
    assert record["device"] == device_name and len(record["strokes"]) == len(run.strokes)
    assert record["stats"]["bytes_received"] == stats.bytes_received
    assert np.allclose(record["strokes"][0]["points"], run.strokes[0].points)


@pytest.mark.parametrize("device_name", ["hp7475a", "grbl"])
def test_instant_time_runs_a_long_job_at_once_with_true_statistics(device_name):
    device, fab = job(device_name, "long")
    port = careful_port(device)
    start = time.perf_counter()
    careful_send(port, device, fab.program.encode())
    wall = time.perf_counter() - start
    stats, total = port.simulator.stats, estimate(wanted(device, fab), device).total
    assert total > 100 and wall < 1.0
    assert stats.busy_time == pytest.approx(total, rel=1e-9)
    assert total <= stats.plot_time < 1.05 * total  # a careful sender hardly starves it
    assert stats.starved_time < 0.05 * total


def stop_at_corners(device):
    """``device`` without a junction deviation: every corner from rest."""
    return replace(device, motion=replace(device.motion, junction_deviation=None))


def rest_to_rest(run, device, runs=None) -> float:
    """Seconds of ``run`` if every straight run of each stroke (``runs`` of its points, default
    the straight runs) went from rest to rest: the stop-at-corners model, written out stroke by
    stroke, each move at its speed and acceleration (scaled per axis where the profile says)."""
    motion = device.motion
    runs = runs or (lambda points: polyline_runs(points, np.zeros(1, dtype=np.intp))[1::2])
    drawn = sum(float(move_times(lengths, *move_limits(steps, s.speed, motion)).sum())
                for s in run.strokes for lengths, steps in [runs(s.points)])
    travel = sum(float(travel_times(np.subtract(t.end, t.start), motion)) for t in run.travels)
    return drawn + travel + 2 * motion.pen_lift_time * len(run.strokes)


def segments(points) -> tuple[np.ndarray, np.ndarray]:
    """The non-zero segments of a polyline, each its own move: lengths and steps."""
    steps = np.diff(points, axis=0)
    lengths = np.hypot(*steps.T)
    return lengths[lengths > 0], steps[lengths > 0]


@pytest.mark.parametrize("device_name", ["hp7475a", "graphtec-ce6000", "grbl"])
def test_without_junction_deviation_the_simulators_stop_at_corners(device_name):
    """HP-GL plotters, and GRBL without $11, move by the stop-at-corners model as before."""
    device, fab = job(device_name)
    device = stop_at_corners(device)
    port = careful_port(device)
    careful_send(port, device, fab.program.encode())
    run = wanted(device, fab)
    busy = port.simulator.stats.busy_time
    assert busy == pytest.approx(rest_to_rest(run, device), rel=1e-9)
    assert busy == pytest.approx(estimate(run, device).total, rel=1e-9)


def circle_gcode(step: float, radius: float = 20.0) -> str:
    """One stroke around a circle sampled every ``step`` mm (a curve turning at every point)."""
    count = int(2 * math.pi * radius / step)
    points = [(150 + radius * math.cos(a), 150 + radius * math.sin(a))
              for a in np.linspace(0, 2 * math.pi, count + 1)]
    lines = [f"X{x:.3f} Y{y:.3f}" for x, y in points[1:]]
    return (f"G21 G90\nG0 Z3\nX{points[0][0]:.3f} Y{points[0][1]:.3f}\nG1 Z-0.3 F600\n"
            f"{lines[0]} F1800\n" + "\n".join(lines[1:]) + "\nG0 Z3\nX0 Y0\nM2\n")


def grbl_busy(device, text: str, **options) -> float:
    port = careful_port(device, **options)
    careful_send(port, device, text.encode())
    assert port.simulator.stats.bytes_lost == 0
    return port.simulator.stats.busy_time


def test_simulated_grbl_plans_with_its_buffer_so_never_beats_the_estimate():
    """GRBL plans corners over the blocks in its planner: as fast as the estimate (unlimited
    look-ahead) when the buffer reaches far enough, a little slower when not, every
    segment from rest to rest with room for one block."""
    device = load_device("grbl")
    fab = fabricate(load_design(ROOT / "jobs" / "vase-svg.toml"), device, spec())
    run = wanted(device, fab)
    total = estimate(run, device).total
    assert grbl_busy(device, fab.program.text) == pytest.approx(total, rel=1e-9)
    one_block = grbl_busy(device, fab.program.text, planner=2)
    assert one_block == pytest.approx(rest_to_rest(run, device, segments), rel=1e-9)
    assert total < one_block < 1.05 * total
    for step, slower in ((0.5, 1.0), (0.05, 1.1)):  # 15 blocks: 7.5 mm, or less than the 0.9 mm to stop
        text = circle_gcode(step)
        total = estimate(interpret(text, device), device).total
        busy = grbl_busy(device, text)
        assert total * (1 - 1e-9) <= busy <= slower * total * (1 + 1e-9)
        assert (busy > total * (1 + 1e-3)) == (slower > 1)
        assert grbl_busy(device, text, planner=64) == pytest.approx(total, rel=1e-9)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.lists(st.tuples(st.integers(10, 60), st.integers(10, 60)), min_size=1, max_size=30),
                min_size=1, max_size=3),
       st.integers(2, 20), st.sampled_from([0.5, 2.0, 0.1]))
def test_simulated_grbl_between_the_estimate_and_stopping_everywhere(strokes, planner, scale):
    device = load_device("grbl")
    text = "G21 G90\nG0 Z3\n"
    for stroke in strokes:
        (x, y), rest = stroke[0], stroke[1:]
        text += f"X{x * scale:g} Y{y * scale:g}\nG1 Z-0.3 F600\nX{x * scale:g} F1800\n"
        text += "".join(f"X{x * scale:g} Y{y * scale:g}\n" for x, y in rest) + "G0 Z3\n"
    run = interpret(text, device)
    busy = grbl_busy(device, text, planner=planner)
    assert estimate(run, device).total * (1 - 1e-9) <= busy
    assert busy <= rest_to_rest(run, device, segments) * (1 + 1e-9)


def test_grbl_status_while_drawing_a_planned_move():
    port, g = grbl()
    port.read_until(b"help]\r\n")
    g.send("G1 Z-0.3 F600\nG1 X50 F1800\nY50\n")  # 90 degrees: the corner passes at 4.13 mm/s
    pause(port, 1.0)
    running = g.status()
    assert running.startswith(b"<Run|MPos:") and running.endswith(b",-0.300|FS:1800,0>")
    x = float(running.split(b"MPos:")[1].split(b",")[0])
    assert 0 < x < 50
    port.simulator.run_until_idle()
    assert g.status() == b"<Idle|MPos:50.000,50.000,-0.300|FS:0,0>"
    # The junction's acceleration is taken along (0, 1) - (1, 0), 45 degrees: 500 · √2 mm/s², so
    # v² = 707.1068 · 0.01 · √½ / (1 - √½) = 17.0710678.  0.2 s pen down, then each 50 mm side:
    # 0.06 s to 30 mm/s, 0.0517366 s to the corner speed (0.9 + 0.8829289 mm) and
    # 48.2170711 mm at 30 mm/s, twice
    side = 0.06 + 0.0517366 + 48.2170711 / 30
    assert port.simulator.stats.busy_time == pytest.approx(0.2 + 2 * side, abs=1e-6)


def test_fast_time_follows_the_wall_clock():
    device = load_device("grbl")
    port = open_port("sim://grbl?time=fast&speedup=100", timeout=10)  # virtual seconds
    assert port.read_until(b"help]\r\n") == BANNER
    start = time.perf_counter()
    port.write(b"G4 P5\n")  # a 5 s dwell: 50 ms of wall time at 100x
    assert port.read_until(b"\r\n") == b"ok\r\n"
    assert 0.04 < time.perf_counter() - start < 0.5
    assert port.simulator.stats.busy_time == pytest.approx(5.0)
    assert port.simulator.clock.now() >= 5.0
    assert device.name == port.simulator.device.name


def test_starvation_is_idle_time_with_work_still_to_come():
    device = load_device("hp7475a")
    port = sim_port(device, timeout=0.5)
    port.write(b"IN;SP1;PU400,400;PD800,400;")
    port.simulator.run_until_idle()
    pause(port, 3.0)  # the sender dawdles while the plotter has nothing to do
    port.write(b"PD800,800;PU0,0;")
    port.simulator.run_until_idle()
    stats = port.simulator.stats
    assert 3.0 < stats.starved_time < 3.2
    assert stats.plot_time == pytest.approx(stats.busy_time + stats.starved_time)
    port.write(b"SP0;")
    port.simulator.run_until_idle()
    pause(port, 2.0)  # parked: the operator's turn, not starvation
    port.write(b"SP1;PD800,400;PU;")
    port.simulator.run_until_idle()
    assert port.simulator.stats.starved_time < 3.3
    (parked,) = port.simulator.stats.pauses
    assert parked.reason == "parked (SP0)" and parked.duration == pytest.approx(2.0, abs=0.1)


# --- GRBL ------------------------------------------------------------------------------


def grbl(timeout=1.0, **options):
    port = sim_port(load_device("grbl"), timeout=timeout, **options)
    return port, Grbl(port)


def test_grbl_banner_ok_per_line_status_and_planner():
    port, g = grbl()
    assert port.read_until(b"help]\r\n") == BANNER
    assert g.status() == b"<Idle|MPos:0.000,0.000,3.000|FS:0,0>"
    g.send("G21 G90\nG0 X10 Y0\nG1 X20 F600\n")
    assert g.replies == [b"ok"] * 3
    running = g.status()
    assert running.startswith(b"<Run|MPos:") and b"|FS:4800,0>" in running  # travel 80 mm/s
    port.simulator.run_until_idle()
    assert g.status() == b"<Idle|MPos:20.000,0.000,3.000|FS:0,0>"
    # the ok of a motion line comes when the line is in the planner: 15 blocks, then wait
    for i in range(20):
        port.write(f"G0 X{i % 2 * 50} Y{i}\n".encode())
    first = port.read(15 * 4)
    assert first.count(b"ok") == 15
    assert port.simulator.stats.bytes_lost == 0 and len(port.simulator.planner) == 15
    pause(port, 0.05)
    assert port.in_waiting == 0  # the first move (50 mm) has not ended yet
    assert port.read_until(b"ok\r\n") == b"ok\r\n"
    port.write(b"$I\n$\n$G\n$$\n$Q\n")
    answer = port.read_until(b"error:3\r\n")
    assert b"[VER:1.1h" in answer and b"[OPT:V,15,128]" in answer and b"$110=4800.000" in answer
    assert b"[HLP:" in answer and b"[GC:G0 G54 G17 G21 G90" in answer


def test_grbl_error_at_unsupported_and_overflow():
    port, g = grbl(error_at=3)
    port.read_until(b"help]\r\n")
    g.send("G21\nG90\nG0 X5\nG2 X1 Y1 I1\nX\n#1\n" + "G1 X1" + " " * 90 + "Y1\n" + "G0" + "0" * 80 + "X1\n")
    assert g.replies == [b"ok", b"ok", b"error:20", b"error:20", b"error:2", b"error:1",
                         b"ok", b"error:11"]
    port.simulator.run_until_idle()
    assert g.status().startswith(b"<Idle|MPos:1.000,1.000")  # "G0 X5" was not executed
    assert port.simulator.stats.errors == ["error:20", "error:20", "error:2", "error:1", "error:11"]


def test_grbl_crlf_gives_an_extra_ok():
    port, g = grbl()
    port.read_until(b"help]\r\n")
    port.write(b"G0 X1\r\n")
    assert port.read(8) == b"ok\r\nok\r\n"


def test_grbl_soft_reset_in_motion_alarms_and_locks():
    port, g = grbl()
    port.read_until(b"help]\r\n")
    g.send("G1 Z-0.3 F600\nG1 X50 F600\nG1 Y50\n")
    pause(port, 0.3)  # the pen is down and moving along the first line
    port.write(b"\x18")
    assert port.read_until(b"unlock]\r\n") == b"ALARM:3\r\n" + BANNER + b"[MSG:'$H'|'$X' to unlock]\r\n"
    assert port.simulator.stats.alarms == ["ALARM:3"]
    assert g.status().startswith(b"<Alarm|")
    drawn = port.simulator.strokes
    assert len(drawn[0].points) == 2 and 0 < drawn[0].length <= 50  # the planned Y move was never drawn
    assert all(s.length == 0 for s in drawn[1:])
    assert port.simulator.machine.stroke is not None  # the reset left the tool down: Z did not move
    g.send("G0 X0\n$X\nG0 Z3\nG0 X0\n")
    assert g.replies[-4:] == [b"error:9", b"ok", b"ok", b"ok"] and b"[MSG:Caution: Unlocked]" in g.messages
    port.simulator.run_until_idle()
    port.write(b"\x18")  # a reset while idle just greets
    assert port.read_until(b"help]\r\n") == BANNER


def test_grbl_realtime_bytes_bypass_a_full_buffer_and_get_no_ok():
    port, g = grbl()
    port.read_until(b"help]\r\n")
    port.write(b"G4 P10\n" + b"G0 X1\n" * 40)  # the dwell holds everything; the buffer fills
    sim = port.simulator
    assert sim.stats.bytes_lost > 0 and len(sim.rx) == 127
    port.write(b"?")
    assert port.read_until(b"\r\n").startswith(b"<Run|")
    port.write(b"!")
    port.write(b"?")
    assert port.read_until(b"\r\n").startswith(b"<Hold:0|")
    port.write(b"~")
    port.write(b"?")
    assert port.read_until(b"\r\n").startswith(b"<Run|")
    assert port.in_waiting == 0  # no ok for realtime bytes
    assert sim.stats.pauses[0].reason == "feed hold"
    port.write(b"\x85\x90")  # extended realtime bytes (jog cancel, feed override) are dropped
    assert len(sim.rx) == 127


def test_grbl_m0_pauses_until_cycle_start():
    device, fab = job("grbl", "two-sided")
    port = careful_port(device)
    port.read_until(b"help]\r\n")
    g = Grbl(port)
    (mark,) = fab.program.pauses
    g.send(fab.program.text[:mark.offset])  # up to and including M0: waits for Hold, sends ~
    assert port.simulator.stats.pauses[0].reason == "M0"
    assert port.simulator.stats.pauses[0].duration >= 0
    g.send(fab.program.text[mark.offset:])
    port.simulator.run_until_idle()
    assert same_strokes(port.simulator.strokes, wanted(device, fab).strokes)
    assert b"[MSG:Pgm End]" in g.messages


def test_grbl_m0_ok_only_after_resume():
    port, g = grbl(timeout=0.5)
    port.read_until(b"help]\r\n")
    port.write(b"G0 X5\nM0\nG0 X10\n")
    assert port.read_until(b"ok\r\n") == b"ok\r\n"  # G0 X5 is in the planner
    assert port.read(4) == b""  # M0 waits for the move, then holds: no ok
    assert g.status().startswith(b"<Hold:0|MPos:5.000")
    port.write(b"~")
    assert port.read(8) == b"ok\r\nok\r\n"


# --- HP-GL -----------------------------------------------------------------------------


def test_hpgl_output_instructions_and_device_control():
    device = load_device("hp7475a")
    port = sim_port(device, timeout=2)
    port.write(b"IN;SP1;PA0,0;PD4000,0;PU;OI;OS;OS;\x1b.B\x1b.L\x1b.E")
    answers = port.read(100).split(b"\r")
    # device control is answered on arrival, while "PU;OI;OS;OS;" waits behind the 100 mm line
    assert answers[:3] == [b"1012", b"1024", b"0"]
    assert answers[3:6] == [device.model.encode(), b"24", b"16"]
    port.write(b"\x1b.A")
    assert port.read_until(b"\r") == device.model.encode() + b"\r"
    port.write(b"SP1;PA400,400;PD;OA;XX;OE;OE;PD1;OE;\x1b.Q\x1b.E")
    answers = port.read(100).split(b"\r")
    assert answers[:2] == [b"11", b"400,400,1"]  # ESC.E: 11 for an unknown ESC. instruction
    assert answers[2:5] == [b"1", b"0", b"2"]  # unknown instruction, none, odd coordinates
    port.write(b"PU;" + b"PD0,0,4000,0;" * 200)  # a naive burst overruns the buffer
    port.write(b"\x1b.E")
    assert port.read_until(b"\r") == b"16\r"


def test_replies_cross_the_wire_at_the_line_rate():
    port, g = grbl()
    port.baudrate = 9600
    sim, byte = port.simulator, 10 / 9600
    sim.run_until_idle()
    port.read(100)  # the banner
    port.write(b"G21\n")
    sent = sim.clock.now()  # the line has arrived and is executed at once
    assert sim.arrived == 0 and sim.out == b"ok\r\n"  # its ok is on the wire
    port.timeout = 1
    assert port.read(4) == b"ok\r\n"
    assert sim.clock.now() == pytest.approx(sent + 4 * byte)
    port.write(b"?")
    asked = sim.clock.now()
    report = port.read_until(b">\r\n")
    assert report.startswith(b"<Idle|") and sim.clock.now() == pytest.approx(asked + len(report) * byte)
    # a reply waits for the wire: the status asked right after $$ comes behind its settings
    port.write(b"$$\n?")
    sent = sim.clock.now()  # "?" has arrived, one byte after "$$\n"
    answer = port.read_until(b">\r\n")
    assert answer.index(b"<Idle|") > answer.index(b"$110=")
    assert sim.clock.now() == pytest.approx(sent - byte + len(answer) * byte)


# --- faults --------------------------------------------------------------------------


def test_disconnect_after_pulls_the_cable():
    device, fab = job("hp7475a")
    port = careful_port(device, disconnect_after=300)
    with pytest.raises(serial.SerialException, match="disconnected"):
        send_escb(port, fab.program.encode())
    sim = port.simulator
    assert sim.stats.bytes_received == 300
    with pytest.raises(serial.SerialException):
        port.read(1)
    with pytest.raises(serial.SerialException):
        port.write(b"IN;")
    sim.run_until_idle()  # the plotter finishes what it received
    drawn = sim.strokes
    assert 0 < len(drawn) < len(wanted(device, fab).strokes)
    port.close()
    port.open()  # plugged back in: the same device
    port.write(b"\x1b.B")  # what the cut left of an instruction still waits in the buffer
    assert 1000 < int(port.read_until(b"\r")) < 1024


def test_error_at_sets_the_hpgl_error():
    device, fab = job("graphtec-ce6000")
    port = careful_port(device, error_at=3)
    port.write(fab.program.encode() + b"OE;OE;")
    assert port.read_until(b"\r") + port.read_until(b"\r") == b"1\r0\r"
    assert port.simulator.stats.errors == ["OE 1"]


def test_error_code_option():
    port, g = grbl(error_at=2, error_code=33)
    port.read_until(b"help]\r\n")
    g.send("G21\nG0 X1\nG0 X2\n")
    assert g.replies == [b"ok", b"error:33", b"ok"]


def test_noise_corrupts_bytes_deterministically():
    device, fab = job("graphtec-ce6000", "long")
    data = fab.program.encode()
    runs = []
    for seed in (1, 1, 2):
        port = careful_port(device, noise=0.01, seed=seed)
        port.write(data)
        port.simulator.run_until_idle()
        runs.append(port.simulator)
    corrupted = [sim.stats.bytes_corrupted for sim in runs]
    assert corrupted[0] == corrupted[1] and corrupted[0] != corrupted[2]
    assert 0.5 * 0.01 * len(data) < corrupted[0] < 1.5 * 0.01 * len(data)
    assert same_strokes(runs[0].strokes, runs[1].strokes)
    assert not same_strokes(runs[0].strokes, wanted(device, fab).strokes)
    assert runs[0].stats.errors  # some corruption makes instructions unreadable


def test_stall_stops_consuming_and_answering_once():
    device, fab = job("hp7475a")
    data = fab.program.encode()
    plain = careful_port(device)
    send_escb(plain, data)
    plain.simulator.run_until_idle()
    stalled = careful_port(device, stall=20, stall_at=400)
    send_escb(stalled, data[:400])
    start = stalled.simulator.clock.now()
    stalled.write(b"\x1b.B")  # asked during the stall: answered when it ends
    assert stalled.read_until(b"\r") != b""
    assert stalled.simulator.clock.now() - start == pytest.approx(20, abs=0.1)
    send_escb(stalled, data[400:])
    stalled.simulator.run_until_idle()
    stats = stalled.simulator.stats
    assert stats.stalled_time == pytest.approx(20)
    assert stats.plot_time == pytest.approx(plain.simulator.stats.plot_time + 20, abs=1.0)
    assert same_strokes(stalled.simulator.strokes, wanted(device, fab).strokes)


def test_mute_device_never_answers():
    port, g = grbl(timeout=0.2, mute=1)
    assert port.read(100) == b""  # no banner
    port.write(b"G0 X1\n?")
    assert port.read(100) == b""
    assert port.simulator.stats.bytes_received == 7
    hpgl = sim_port(load_device("graphtec-ce6000"), timeout=0.2, mute=1)
    assert not hpgl.cts and not hpgl.dsr
    hpgl.write(b"\x1b.BOI;")
    assert hpgl.read(10) == b""
    xon = sim_port(load_device("roland-gx24"), timeout=0.2, mute=1, flow="xonxoff")
    xon.write(b"PD0,0,4000,0;" * 400)
    assert xon.read(10) == b"" and xon.simulator.stats.xoff_sent == 0
    assert xon.simulator.stats.bytes_lost > 0


def test_write_takes_bytes_only():
    port, _ = grbl()
    with pytest.raises(TypeError, match="zero bytes"):
        port.write(5)
    with pytest.raises(TypeError):
        port.write("G0 X1\n")
    assert port.simulator.stats.bytes_received == 0
    assert port.write(bytearray(b"G0 X1\n")) == 6 and port.write(memoryview(b"?")) == 1


def test_options_are_checked():
    assert parse_options([("noise", "0.5"), ("sheet", "A4 landscape"), ("mute", "1")]) == \
        SimOptions(noise=0.5, sheet=(297.0, 210.0), mute=True)
    for key, value in (("noise", "2"), ("time", "slow"), ("buffer", "-1"), ("nosie", "0.1")):
        with pytest.raises(FoldfabError, match=key):
            parse_options([(key, value)])
    with pytest.raises(FoldfabError, match="unknown option 'nosie'; did you mean 'noise'"):
        parse_options([("nosie", "0.1")])
    register_handlers()
    with pytest.raises(serial.SerialException, match="unknown option"):
        serial.serial_for_url("sim://grbl?bogus=1")


def test_write_timeout_when_flow_control_holds():
    port = sim_port(load_device("graphtec-ce6000"), rtscts=True, mute=1)  # CTS stays low
    port.write_timeout = 0.5
    start = port.simulator.clock.now()
    with pytest.raises(serial.SerialTimeoutException):
        port.write(b"IN;")
    assert port.simulator.clock.now() - start == pytest.approx(0.5, abs=0.01)
    assert port.simulator.stats.bytes_received == 0


# --- on a real pseudo-terminal ------------------------------------------------------


class PtyServer:
    """serve_pty in a thread."""

    def __init__(self, device_name: str, **options):
        self.stop, self.ready = threading.Event(), threading.Event()
        options = SimOptions(time="fast", speedup=200, sheet=(297.0, 420.0), **options)
        self.sim = create_simulator(load_device(device_name), options)
        self.thread = threading.Thread(target=serve_pty, args=(self.sim, self._ready, self.stop))
        self.thread.start()
        assert self.ready.wait(5)

    def _ready(self, path):
        self.path = path
        self.ready.set()

    def wait_done(self, received: int, idle: bool = True, limit: float = 20.0) -> None:
        """Wait until the device has received ``received`` bytes (and, if ``idle``, done them)."""
        end = time.monotonic() + limit
        while self.sim.stats.bytes_received < received or \
                (idle and self.sim.next_event() != float("inf")):
            assert time.monotonic() < end, "the simulated plotter did not finish"
            time.sleep(0.02)

    def close(self):
        self.stop.set()
        self.thread.join(5)
        return self.sim


def test_pty_xonxoff_by_the_kernel_loses_nothing_naive_loses():
    device, fab = job("roland-gx24")
    data = fab.program.encode()
    results = {}
    for xonxoff in (True, False):
        server = PtyServer("roland-gx24", flow="xonxoff", buffer=256)
        port = serial.Serial(server.path, device.serial.baudrate, xonxoff=xonxoff, timeout=1)
        port.write(data)  # one write; with IXON the kernel stops at XOFF
        server.wait_done(len(data), idle=xonxoff)  # garbled moves can take the naive one hours
        port.close()
        results[xonxoff] = server.close()
    careful, naive = results[True], results[False]
    assert careful.stats.bytes_lost == 0 and careful.stats.xoff_sent > 0
    assert same_strokes(careful.strokes, wanted(device, fab).strokes)
    assert naive.stats.bytes_lost > 0
    assert not same_strokes(naive.strokes, wanted(device, fab).strokes)


def test_pty_grbl_character_counting():
    device, fab = job("grbl")
    server = PtyServer("grbl")
    port = serial.Serial(server.path, 115200, timeout=2)
    port.write(b"\x18")  # the pty does not notice opens: ask for a banner
    assert port.read_until(b"help]\r\n").endswith(BANNER)
    Grbl(port).send(fab.program.text)
    port.close()
    server.wait_done(len(fab.program.text) + 1)
    sim = server.close()
    assert sim.stats.bytes_lost == 0
    assert same_strokes(sim.strokes, wanted(device, fab).strokes)


def test_pty_serves_in_instant_time_and_reports_the_job():
    """Issue 18: foldfab sim accepts what sim:// accepts, instant time too (the device runs as fast
    as it is simulated while the host is silent), and reports each job as it ends."""
    device, fab = job("grbl")
    stop, jobs, ready = threading.Event(), [], threading.Event()
    sim = create_simulator(device, SimOptions(time="instant", sheet=(297.0, 420.0)))
    paths = []
    thread = threading.Thread(target=serve_pty, args=(sim, lambda p: paths.append(p) or ready.set(), stop,
                                                      jobs.append))
    thread.start()
    try:
        assert ready.wait(5)
        port = serial.Serial(paths[0], 115200, timeout=5)
        port.write(b"\x18")
        assert port.read_until(BANNER).endswith(BANNER)
        Grbl(port).send(fab.program.text)
        port.close()
        deadline = time.monotonic() + 60
        while not jobs:  # M2 ends the job: reported while serving
            assert time.monotonic() < deadline, "no job reported"
            time.sleep(0.02)
    finally:
        stop.set()
        thread.join(10)
    want = wanted(device, fab)
    assert same_strokes(sim.strokes, want.strokes) and sim.stats.bytes_lost == 0
    assert len(jobs) == 1 and jobs[0].drawn == pytest.approx(sum(s.length for s in want.strokes))
    assert jobs[0].end - jobs[0].start == pytest.approx(estimate(want, device).total, rel=0.05)


@pytest.mark.parametrize("device_name, first, second", [
    ("grbl", b"G1 Z-0.3 F600\nG1 X10\n", b"G1 Y10\n"),  # no M2: only the host's silence ends the job
    ("hp7475a", b"IN;SP1;PD400,0;SP0;", b"IN;SP1;PD400,400;SP0;")])
def test_the_wait_between_two_jobs_is_no_starvation(device_name, first, second):
    """Issue 18: 'starved 1796 s' after one short job: the time before a job's first byte and after
    its last is no starvation (nor a pause); each job is recorded with its bytes, length and time."""
    sim = create_simulator(load_device(device_name), SimOptions(time="instant"))
    sim.connect()
    _, done = sim.transmit(first, 100.0)  # the host came after 100 s
    sim.run_until(lambda: False, done + 60)
    assert sim.end_job() is not None
    _, done = sim.transmit(second, done + 1800)  # and again half an hour later
    sim.run_until(lambda: False, done + 60)
    sim.end_job(force=True)
    stats = sim.stats
    assert stats.starved_time < 1 and stats.paused_time < 1, stats.summary()
    assert [(j.number, j.received) for j in stats.jobs] == [(1, len(first)), (2, len(second))]
    assert [round(j.drawn, 6) for j in stats.jobs] == [10.0, 10.0]
    assert all(0 < j.end - j.start < 60 for j in stats.jobs)
    assert stats.plot_time == pytest.approx(sum(j.end - j.start for j in stats.jobs))


def test_foldfab_sim_command(tmp_path):
    device, fab = job("hp7475a")
    record, svg = tmp_path / "run.json", tmp_path / "run.svg"
    proc = subprocess.Popen(  # issue 18: no --pty needed (the only mode)
        [sys.executable, "-m", "foldfab", "sim", "hp7475a", "--time", "fast",
         "-o", f"sheet={SHEET}", "--option", "speedup=200", "--record", str(record), "--svg", str(svg)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        path = proc.stdout.readline().strip()
        assert path.startswith("/dev/")
        port = serial.Serial(path, 9600, timeout=2)
        send_escb(port, fab.program.encode())
        port.write(b"OA;")  # answered once every move before it has ended
        assert port.read_until(b"\r").endswith(b",0\r")
        port.close()
        served = proc.stdout.readline()  # printed while serving, once the host has gone quiet
    finally:
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    length = sum(s.length for s in wanted(device, fab).strokes)
    assert re.fullmatch(rf"job 1 +received \d+ bytes, drew {length:.1f} mm in [\d.]+ s\n", served), served
    assert f"strokes      {len(wanted(device, fab).strokes)} drawn" in out
    assert "0 lost" in out and "wrote" in out
    drawing = svg.read_text()  # each pen in its layer's colour, as foldfab's own preview draws it
    for layer, colour in (("valley", "#0000ff"), ("mountain", "#ff0000"), ("cut", "#000000")):
        assert re.search(rf'data-layer="{layer}" fill="none" stroke="{colour}"', drawing), layer
    assert json.loads(record.read_text())["stats"]["bytes_lost"] == 0


def test_foldfab_sim_accepts_instant_time(tmp_path):
    run = subprocess.run([sys.executable, "-m", "foldfab", "sim", "grbl", "--time", "slow"],
                         capture_output=True, text=True, cwd=ROOT)
    assert run.returncode == 2 and "time='slow': expected real, fast or instant" in run.stderr
    proc = subprocess.Popen([sys.executable, "-m", "foldfab", "sim", "grbl", "--time", "instant"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        port = serial.Serial(proc.stdout.readline().strip(), 115200, timeout=5)
        port.write(b"\x18")
        assert port.read_until(BANNER).endswith(BANNER)  # (after what is left of the greeting on start)
        port.write(b"G1 Z-1 F600\nG1 X100 F60\nM2\n")  # 100 s of drawing, at once
        assert port.read_until(b"Pgm End]\r\nok\r\n").endswith(b"ok\r\nok\r\n[MSG:Pgm End]\r\nok\r\n")
        port.close()
        served = proc.stdout.readline()
    finally:
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    found = re.fullmatch(r"job 1 +received \d+ bytes, drew 100\.0 mm in ([\d.]+) s\n", served)
    assert found and 100 < float(found.group(1)) < 110, served  # the simulated plotter's time


def test_foldfab_sim_command_errors():
    run = subprocess.run([sys.executable, "-m", "foldfab", "sim", "grbl", "--pty", "-o", "noise"],
                         capture_output=True, text=True, cwd=ROOT)
    assert run.returncode == 2 and "KEY=VALUE" in run.stderr
    run = subprocess.run([sys.executable, "-m", "foldfab", "sim", "nope", "--pty"],
                         capture_output=True, text=True, cwd=ROOT)
    assert run.returncode == 2 and "unknown device 'nope'" in run.stderr


def test_create_simulator_without_a_port():
    device = load_device("hp7475a")
    sim = create_simulator(device, SimOptions(time="instant"))
    text = "IN;SP1;PA0,0;PD400,0;PU;"
    sent, done = sim.transmit(text.encode(), 0.0)
    assert sent == len(text) and done == pytest.approx(len(text) * 10 / 9600)  # 8N1 at 9600 baud
    sim.run_until_idle()
    assert same_strokes(sim.strokes, interpret(text, device).strokes)


def test_a_new_port_plugs_into_the_same_device():
    """After a pulled cable, a new port object given the simulator reaches the same board."""
    device, fab = job("grbl")
    port, g = grbl(timeout=60, disconnect_after=600, reset_on_open=0)
    assert port.read(1) == b""  # this bridge does not reset the board: no banner
    with pytest.raises(serial.SerialException, match="disconnected"):
        g.send(fab.program.text)
    sim = port.simulator
    sim.run_until_idle()  # the board finishes its planner while unplugged
    drawn = len(sim.strokes)
    again = serial.serial_for_url("sim://grbl", do_not_open=True, baudrate=115200, timeout=1)
    again.simulator = sim
    again.open()
    assert again.in_waiting == 0 and len(sim.strokes) == drawn
    again.write(b"?")
    assert again.read_until(b"\r\n").startswith(b"<Idle|")  # position kept, no alarm
    again.write(b"\x18")
    assert again.read_until(b"help]\r\n") == BANNER


def test_a_session_reopened_resets_the_board_as_it_is_now():
    """The board runs on while no port is open: a port opened after the last move has ended resets
    an idle board (no alarm: a queue's next job after a cancelled one), one opened during a move
    stops it (ALARM:3)."""
    url = "sim://grbl?time=fast&speedup=20&session=test-reopen-{}"
    port = open_port(url.format(1), timeout=2)
    assert port.read_until(b"help]\r\n") == BANNER
    port.write(b"G0 Z5\nG0 X20\n")  # what a cancelled job's last words are: the pen up, parked
    assert port.read_until(b"ok\r\nok\r\n") == b"ok\r\nok\r\n"
    port.close()
    sim = port.simulator
    end = sim.next_event()
    assert sim.clock.now() < end < math.inf  # closed while the board still moves
    deadline = time.monotonic() + 60
    while sim.clock.now() <= end:  # until the board is at rest
        assert time.monotonic() < deadline, "the simulated board never came to rest"
        time.sleep(0.005)  # poll interval
    again = open_port(url.format(1), timeout=2)
    assert again.simulator is sim
    assert again.read_until(b"help]\r\n") == BANNER
    assert sim.stats.alarms == [] and not sim.alarm
    again.write(b"?")
    assert again.read_until(b"\r\n").startswith(b"<Idle|MPos:20.000,")
    again.close()

    port = open_port(url.format(2), timeout=2)
    port.read_until(b"help]\r\n")
    port.write(b"G1 X200 F100\n")  # two minutes of virtual time, six seconds of wall time
    assert port.read_until(b"ok\r\n") == b"ok\r\n"
    port.close()
    again = open_port(url.format(2), timeout=2)
    assert again.read_until(b"unlock]\r\n") == b"ALARM:3\r\n" + BANNER + b"[MSG:'$H'|'$X' to unlock]\r\n"
    again.close()


def test_recorded_svg_names_strokes_by_the_layer_whose_tool_drew_them():
    """A device gets tools, not layer names: the SVG names each stroke by the profile's layer with
    that tool; layers sharing one tool share a name and the first one's colour."""
    from foldfab.programs.preview import layer_color
    from foldfab.sim.record import layer_named

    device = load_device("graphtec-ce6000")  # valley and mountain: pen 1, force 6; cut: force 18
    stroke = interpret("IN;SP1;FS6;PD100,0;PU;FS18;PD0,100;PU;FS30;PD100,100;", device).strokes
    names = [s.layer for s in layer_named(stroke, device)]
    assert names == ["valley+mountain", "cut", "pen 1"]
    assert [layer_color(n) for n in names] == ["#0000ff", "#000000", "#808080"]
