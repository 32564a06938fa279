"""Streaming engines against the simulated plotters (sim:// and a real pseudo-terminal).

The simulators speak the devices' wire protocols and lose what overruns their receive
buffers, so "the recorded strokes equal the program's strokes, in order, and no byte
was lost" is the test of a sender.  :class:`Spy` wraps every port: it fails a test on a
write of anything but ``bytes`` and counts GRBL's unacknowledged bytes.
"""

from __future__ import annotations

import queue
import time
import re
import signal
import subprocess
import sys
import threading
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from foldfab.design import load_design
from foldfab.devices import BufferSettings, load_device
from foldfab.fabricate import fabricate
from foldfab.fabrication.spec import parse_fabrication
from foldfab.plotting.progress import JobProgress
from foldfab.errors import FoldfabError
from foldfab.programs.hpgl import write_hpgl
from foldfab.fabrication.plan import Pass, PlotPlan
from foldfab.programs.languages import write_program
from foldfab.plotting.engines.base import CHECK_EVERY, StreamStopped
from foldfab.plotting.engines.grbl import GRBL_RX_BUFFER
from foldfab.plotting.stream import stream
from foldfab.plotting.transport import open_port
from helpers import JOBS, ROOT
from helpers.plans import make_document, sample_plan
from helpers.streams import (FAST_BAUD, FLOWS, SIM, ScriptedGrbl, Spy, device_for, fabricated, same_strokes,
                             sim_port, strokes_of)


DEVICE_NAMES = [*FLOWS, "xonxoff"]


def run(port, program, device, **kw):
    """Stream and collect the progress events."""
    events = []
    result = stream(port, program, device, events=events.append, operator=lambda message: True, **kw)
    return result, events


# --- every job on every device type ----------------------------------------------------------


@pytest.mark.parametrize("name", DEVICE_NAMES)
@pytest.mark.parametrize("job", JOBS, ids=[j.stem for j in JOBS])
def test_every_job_every_device_draws_the_program(job, name, xonxoff_device):
    """The simulator draws exactly the program's strokes, in order, and loses nothing."""
    device = device_for(name, xonxoff_device)
    fab = fabricated(str(job), xonxoff_device if name == "xonxoff" else name)
    port = sim_port(device, baudrate=FAST_BAUD)
    result, events = run(port, fab.program, device)
    sim = port.simulator
    assert sim.stats.bytes_lost == 0 and not sim.stats.errors
    assert same_strokes(sim.strokes, strokes_of(fab.program, device))
    assert result.sent == len(fab.program.text)
    assert port.max_in_flight <= GRBL_RX_BUFFER
    acked = [e.acknowledged for e in events]
    assert acked == sorted(acked) and events[0].kind == "start" and events[-1].kind == "done"
    assert events[-1].fraction == 1.0 and events[-1].strokes_done == events[-1].strokes_total


def marker_offsets(written: bytes, program: bytes) -> list[int]:
    """Program offsets after which the sender wrote an inline ``OE;`` (checkpoints included),
    checking that the rest of what it wrote is the program, a setup ``OS;``, position questions
    (``OA;``) and device-control questions (``ESC.B``)."""
    offsets, rest = [], bytearray()
    for part in re.split(rb"(OE;|OS;|OA;|\x1b\.B)", written):
        if part == b"OE;":
            offsets.append(len(rest))
        elif part not in (b"OS;", b"OA;", b"\x1b.B"):
            rest += part
    assert bytes(rest) == program
    return offsets


def fast_motion_profile(folder: Path) -> Path:
    """The Graphtec with motion so fast that the link is always the bottleneck."""
    text = (ROOT / "devices" / "graphtec-ce6000.toml").read_text()
    text = re.sub(r"(?m)^(travel_speed|acceleration) = .*$", r"\1 = 100000000", text)
    text = re.sub(r"(?m)^pen_lift_time = .*$", "pen_lift_time = 0", text)
    text = text.replace("speed = [10, 600]", "speed = [10, 100000000]")
    text = re.sub(r"(?m)^speed = (100|200)$", "speed = 100000000", text)
    path = folder / "graphtec-fast.toml"
    path.write_text(text.replace('name = "graphtec-ce6000"', 'name = "graphtec-fast"'))
    return path


@pytest.mark.parametrize("name", ["hp7475a", "graphtec-ce6000", "roland-gx24", "xonxoff"])
def test_an_inline_marker_follows_each_stroke_while_the_link_has_time_to_spare(name, xonxoff_device):
    device = device_for(name, xonxoff_device)
    program = fabricated(str(ROOT / "jobs/hexagon-fig8a.toml"), xonxoff_device if name == "xonxoff" else name).program
    port = sim_port(device, baudrate=FAST_BAUD)
    run(port, program, device)
    ends = JobProgress(program, device).ends
    marked = marker_offsets(bytes(port.written), program.encode())
    assert set(ends) <= set(marked)  # each stroke's end is confirmed on its own
    assert len(marked) <= len(ends) + 3  # besides them only the setup's and the last checkpoint
    assert port.simulator.stats.bytes_lost == 0
    if device.buffer.flow_control == "escb":  # no ESC.B while a marker's answer is to come:
        # only before the setup's checkpoint and while the last one drains the buffer
        oe = [m.start() for m in re.finditer(rb"OE;", bytes(port.written))]
        asked = [m.start() for m in re.finditer(rb"\x1b\.B", bytes(port.written))]
        assert asked and not [a for a in asked if oe[0] < a < oe[-2]]


def test_no_inline_markers_where_the_link_is_the_bottleneck(tmp_path):
    device = load_device(fast_motion_profile(tmp_path))
    spec = parse_fabrication({"sheet": "A3", "margin": 5, "scale": 0.4}, "test")
    program = fabricate(load_design(ROOT / "jobs/vase-svg.toml"), device, spec).program
    port = sim_port(device, baudrate=9600)
    run(port, program, device)
    marked = marker_offsets(bytes(port.written), program.encode())
    # only the checkpoints' (the setup, the end) and the window's: one every half window (256 bytes),
    # so the window moves on without a round trip (markers would cost 3 bytes a stroke)
    assert len(marked) <= len(program.encode()) // (CHECK_EVERY // 2) + 3
    assert np.all(np.diff(marked[1:-1]) >= CHECK_EVERY // 2)  # (the last one ends the program)


@pytest.mark.parametrize("name", DEVICE_NAMES)
def test_two_sided_job_pauses_for_the_flip_and_is_answered(name, xonxoff_device):
    """The flip pause is asked once, after everything before it was executed; without an
    operator the job stops there, safely."""
    device = device_for(name, xonxoff_device)
    fab = fabricated(str(ROOT / "jobs/star.toml"), xonxoff_device if name == "xonxoff" else name,
                     "two-sided")
    want = strokes_of(fab.program, device)
    (pause,) = fab.program.pauses
    before = sum(s.end <= pause.offset for s in want)
    port = sim_port(device, baudrate=FAST_BAUD)
    asked = []

    def operator(message):
        asked.append((message, len(port.simulator.strokes)))
        return True

    stream(port, fab.program, device, operator=operator)
    assert asked == [(pause.message, before)]
    assert same_strokes(port.simulator.strokes, want)

    port = sim_port(device, baudrate=FAST_BAUD)
    with pytest.raises(StreamStopped, match="nobody to answer") as stop:
        stream(port, fab.program, device)
    assert stop.value.lifted and not stop.value.cancelled
    assert len(port.simulator.strokes) == before
    assert JobProgress(fab.program, device).strokes_done(stop.value.acknowledged) == before


# --- instructions longer than the buffer ------------------------------------------------------


def small_buffer_device(flow: str, size: int):
    """The HP 7475A with a ``size``-byte buffer and the handshake ``flow``."""
    device = load_device("hp7475a")
    serial = replace(device.serial, xonxoff=flow == "xonxoff", rtscts=flow == "rtscts")
    return replace(device, serial=serial, buffer=BufferSettings(size, flow))


def long_lines_plan(device) -> PlotPlan:
    """Two lines of 30 and 12 points: PD lists of hundreds of bytes on one sheet."""
    zigzag = [complex(20 + 6 * k, 40 + 30 * (k % 2)) for k in range(30)]
    spiral = [complex(150 + 40 * np.cos(k), 120 + 40 * np.sin(k)) for k in range(12)]
    return PlotPlan(make_document({1: [zigzag, spiral]}), [Pass(1, "valley", device.tool_for("valley"))],
                    device.sheet)


@settings(max_examples=24, deadline=None)
@given(st.sampled_from(["escb", "xonxoff", "rtscts", "none"]), st.integers(32, 300))
def test_lines_longer_than_the_buffer_stream_with_every_flow_control(flow, size):
    """A 300-byte PD on a 32-byte buffer: written in pieces that fit, drawn exactly, no stall."""
    device = small_buffer_device(flow, size)
    program = write_hpgl(long_lines_plan(device), device)
    port = sim_port(device, f"buffer={size}", baudrate=FAST_BAUD)
    run(port, program, device, stall_timeout=3.0)
    assert port.simulator.stats.bytes_lost == 0 and not port.simulator.stats.errors
    assert same_strokes(port.simulator.strokes, strokes_of(program, device))
    assert len(strokes_of(program, device)) == 2


def test_a_program_with_an_instruction_longer_than_the_buffer_allows_is_refused_before_sending():
    """A program written for a larger buffer would deadlock the sender: a one-line error instead."""
    big, small = small_buffer_device("escb", 1024), small_buffer_device("escb", 64)
    program = write_hpgl(long_lines_plan(big), big)
    port = sim_port(small, "buffer=64", baudrate=FAST_BAUD)
    with pytest.raises(FoldfabError, match=r"program instruction at byte \d+ is \d+ bytes long; "
                                           r"hp7475a's 64-byte buffer takes HP-GL instructions of at most 61"):
        run(port, program, small)
    assert not port.written


# --- line noise that keeps the program valid: position checks ------------------------------------


class Garble(Spy):
    """Line noise that keeps the program valid: the last byte of the ``occurrence``-th
    ``pattern`` the host writes arrives as ``replacement``."""

    def __init__(self, port, pattern: bytes, replacement: bytes, occurrence: int):
        super().__init__(port, grbl=port.simulator.protocol == "gcode")
        object.__setattr__(self, "_garble", [pattern, replacement, occurrence, b""])

    def write(self, data):
        pattern, replacement, occurrence, tail = self._garble
        out = bytearray()
        for byte in data:
            tail = (tail + bytes([byte]))[-len(pattern):]
            if tail == pattern:
                occurrence -= 1
                if occurrence == 0:
                    byte = replacement[0]
            out.append(byte)
        self._garble[2:] = [occurrence, tail]
        return super().write(bytes(out))


def garbled_park(name: str, occurrence: int, xonxoff_device: str):
    """The sample plan (a pause, then the end) on ``name``, with the ``occurrence``-th park's
    last digit garbled in transit."""
    device = device_for(name, xonxoff_device)
    program = write_program(sample_plan(device), device)
    if device.protocol == "hpgl":
        pattern = "PU{},{}".format(*device.park_units)
    else:
        # after a Z or servo lift G0 is modal: a bare "X.. Y.."; after a laser's G1 moves and M5, "G0 X.. Y.."
        pattern = ("\nG0 " if device.laser else "\n") + "X{:g} Y{:g}".format(*device.motion.park)
    assert program.text.count(pattern) == 2  # the park before the pause, and at the end
    wrong = str((int(pattern[-1]) + 5) % 10).encode()
    port = open_port(SIM, device, baudrate=FAST_BAUD)
    return device, program, Garble(port, pattern.encode(), wrong, occurrence)


@pytest.mark.parametrize("name", DEVICE_NAMES)
@pytest.mark.parametrize("occurrence", [1, 2], ids=["at-the-pause", "at-the-end"])
def test_a_pen_position_that_disagrees_with_the_program_stops_the_job(name, occurrence, xonxoff_device):
    """A digit garbled in transit is valid HP-GL or G-code: no plotter error.  The position
    read back (HP-GL OA, GRBL MPos) at the pause and at the end tells: the job stops there,
    the tool lifted, the operator is not asked, it is not reported done, and its resume
    point is the last check that agreed."""
    device, program, port = garbled_park(name, occurrence, xonxoff_device)
    asked = []
    with pytest.raises(StreamStopped) as stop:
        stream(port, program, device, operator=lambda message: asked.append(message) or True)
    assert "expected 0,0" in str(stop.value) and "line noise or lost steps" in str(stop.value)
    assert stop.value.lifted and stop.value.plotter_error and not stop.value.cancelled
    (pause,) = program.pauses
    assert len(asked) == occurrence - 1
    if occurrence == 1:
        assert stop.value.acknowledged < pause.offset
    else:  # a resume draws again from the last check that agreed: at the pause (GRBL: its M0 line)
        assert pause.offset - len("M0\n") <= stop.value.acknowledged <= pause.offset
    assert port.simulator.stats.bytes_lost == 0


@pytest.mark.parametrize("name", ["hp7475a", "graphtec-ce6000", "roland-gx24", "xonxoff"])
def test_an_hpgl_job_is_done_once_its_last_position_check_agreed(name, xonxoff_device):
    device, program, port = garbled_park(name, 3, xonxoff_device)  # nothing garbled
    result = stream(port, program, device, operator=lambda message: True)
    assert result.sent == len(program.text)
    written = bytes(port.written)  # the last question of the job is where the pen is
    assert b"OE;OA;" in written[written.rindex(program.text[-10:].encode()):]


def position_markers(written: bytes) -> list[int]:
    """Program offsets after which the sender asked ``OE;OA;`` (checkpoints included)."""
    offsets, program = [], 0
    for part in re.split(rb"(OE;OA;|OE;|OS;|OA;|\x1b\.B)", written):
        if part == b"OE;OA;":
            offsets.append(program)
        elif part not in (b"OE;", b"OS;", b"OA;", b"\x1b.B"):
            program += len(part)
    return offsets


@pytest.mark.parametrize("name", ["hp7475a", "graphtec-ce6000", "roland-gx24", "xonxoff"])
def test_inline_markers_carry_position_checks_mid_job(name, xonxoff_device):
    """A motion-bound job (inline markers, no draining checkpoints): every 2048 bytes a
    marker asks OA too; a stroke's last coordinate garbled before one stops the job there."""
    device = device_for(name, xonxoff_device)
    program = fabricated(str(ROOT / "jobs/vase-svg.toml"), xonxoff_device if name == "xonxoff" else name).program
    clean = sim_port(device, baudrate=FAST_BAUD)
    run(clean, program, device)
    ends = set(JobProgress(program, device).ends)
    mid_job = [offset for offset in position_markers(bytes(clean.written)) if offset in ends]
    assert len(mid_job) >= len(program.text) // 2048 - 1
    offset = mid_job[0]
    pattern = program.text[offset - 8:offset - 1]  # ends with the stroke's last digit
    wrong = str((int(pattern[-1]) + 5) % 10).encode()
    port = Garble(open_port(SIM, device, baudrate=FAST_BAUD), pattern.encode(), wrong,
                  program.text[:offset].count(pattern))
    with pytest.raises(StreamStopped) as stop:
        run(port, program, device)
    assert f"after program byte {offset}: line noise or lost steps" in str(stop.value)
    assert stop.value.acknowledged < offset and stop.value.plotter_error and stop.value.lifted


# --- a naive sender loses data, foldfab does not ---------------------------------------------

NAIVE_CASES = ["xonxoff", "xonxoff-by-foldfab", "rtscts", "escb", "grbl", "none"]


def naive_and_careful(case: str, xonxoff_device: str):
    name = {"xonxoff": "xonxoff", "xonxoff-by-foldfab": "xonxoff", "rtscts": "graphtec-ce6000",
            "escb": "hp7475a", "grbl": "grbl", "none": "roland-gx24"}[case]
    device = device_for(name, xonxoff_device)
    fab = fabricated(str(ROOT / "jobs/vase-svg.toml"), xonxoff_device if name == "xonxoff" else name)
    # foldfab-honoured XON/XOFF: the port's driver does not handle it (sockets, --no-xonxoff)
    port_flow = {"xonxoff": False} if case == "xonxoff-by-foldfab" else {}
    if name == "xonxoff":  # a buffer smaller than the second of work foldfab queues: XOFF comes
        device = replace(device, buffer=replace(device.buffer, size=64))
    return device, fab, port_flow


@pytest.mark.parametrize("case", NAIVE_CASES)
def test_naive_sender_loses_data_on_the_simulator_foldfab_does_not(case, xonxoff_device):
    device, fab, port_flow = naive_and_careful(case, xonxoff_device)
    naive = open_port(SIM, device, xonxoff=False, rtscts=False)  # write it all at once
    naive.write(fab.program.encode())
    naive.simulator.run_until_idle()
    assert naive.simulator.stats.bytes_lost > 0
    assert not same_strokes(naive.simulator.strokes, strokes_of(fab.program, device))

    small = f"buffer={device.buffer.size}"
    port = sim_port(device, small, baudrate=FAST_BAUD, **port_flow)
    run(port, fab.program, device)
    assert port.simulator.stats.bytes_lost == 0
    assert same_strokes(port.simulator.strokes, strokes_of(fab.program, device))
    if case.startswith("xonxoff"):
        assert port.simulator.stats.xoff_sent > 0  # held at XOFF (by foldfab, or by the driver)


@pytest.fixture
def pty_plotter(tmp_path):
    """``foldfab sim NAME --pty`` in a subprocess: yields a function that starts one
    and returns its /dev/pts path; the recording is read back after SIGINT."""
    started = []

    def start(device: str, *options: str, time: str = "fast"):
        record = tmp_path / f"record{len(started)}.json"
        args = [sys.executable, "-m", "foldfab", "sim", device, "--pty", "--time", time,
                "--record", str(record)]
        for option in ("sheet=A3", *options):
            args += ["-o", option]
        proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
        path = proc.stdout.readline().strip()
        assert path.startswith("/dev/"), proc.stderr.read()
        started.append((proc, record))
        return path, proc, record

    yield start
    for proc, _ in started:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def stop_pty(proc, record: Path) -> dict:
    import json

    proc.send_signal(signal.SIGINT)
    proc.communicate(timeout=30)
    return json.loads(record.read_text())


PTY_CASES = {"xonxoff": "xonxoff", "rtscts": "graphtec-ce6000", "escb": "hp7475a", "grbl": "grbl"}
"""On a pty the termios driver does XON/XOFF (IXON) and RTS/CTS (CRTSCTS), as on a real port."""


@pytest.mark.parametrize("case", list(PTY_CASES))
def test_foldfab_loses_nothing_over_a_pseudo_terminal(case, xonxoff_device, pty_plotter):
    """Over a real pty (kernel buffers and termios), for each flow control."""
    name = PTY_CASES[case]
    device = device_for(name, xonxoff_device)
    fab = fabricated(str(ROOT / "jobs/hexagon-fig8a.toml"), xonxoff_device if name == "xonxoff" else name)
    if device.protocol == "hpgl":  # a small buffer: the job overruns it several times
        device = replace(device, buffer=replace(device.buffer, size=256))
    path, proc, record = pty_plotter(xonxoff_device if name == "xonxoff" else name,
                                     *(["buffer=256"] if device.protocol == "hpgl" else []))
    port = Spy(open_port(path, device), grbl=device.protocol == "gcode")
    try:
        stream(port, fab.program, device, stall_timeout=10)
    finally:
        port.close()
    recording = stop_pty(proc, record)
    assert recording["stats"]["bytes_lost"] == 0 and not recording["stats"]["errors"]
    want = strokes_of(fab.program, device)
    assert len(recording["strokes"]) == len(want)
    assert all(np.allclose(got["points"], s.points, atol=1e-5) for got, s in zip(recording["strokes"], want))
    assert port.max_in_flight <= GRBL_RX_BUFFER


def test_a_naive_sender_loses_data_over_a_pseudo_terminal():
    """The same pty plotter overruns when its handshake is ignored (waits for the first lost
    byte, not for a time)."""
    from foldfab.sim import create_simulator, parse_options
    from foldfab.sim.pty import serve_pty

    device = load_device("hp7475a")
    fab = fabricated(str(ROOT / "jobs/hexagon-fig8a.toml"), "hp7475a")
    sim = create_simulator(device, parse_options([("time", "real"), ("buffer", "256"), ("sheet", "A3")], "test"))
    stop, paths = threading.Event(), queue.Queue()
    server = threading.Thread(target=serve_pty, args=(sim, paths.put, stop), daemon=True)
    server.start()
    try:
        port = open_port(paths.get(timeout=20), device)
        port.write(fab.program.encode())
        port.flush()
        deadline = time.monotonic() + 4 * len(fab.program.text) / 960 + 60
        while sim.stats.bytes_lost == 0:
            assert time.monotonic() < deadline and sim.stats.bytes_received < len(fab.program.text), \
                "every byte arrived and none was lost"
            time.sleep(0.02)  # poll interval
        port.close()
    finally:
        stop.set()
        server.join(20)


# --- GRBL --------------------------------------------------------------------------------------


def grbl_job(strategy: str = "force"):
    device = load_device("grbl")
    return device, fabricated(str(ROOT / "jobs/star.toml"), "grbl", strategy)


def test_grbl_waits_for_the_banner_and_provokes_one_with_a_soft_reset():
    device, fab = grbl_job()
    port = sim_port(device, "reset_on_open=0")
    run(port, fab.program, device)
    assert port.written.startswith(b"\x18")  # no banner came: a soft reset brought one
    assert same_strokes(port.simulator.strokes, strokes_of(fab.program, device))

    port = sim_port(device)  # the board greets when the port opens: no reset
    run(port, fab.program, device)
    assert b"\x18" not in port.written


def test_grbl_mute_board_is_an_error_not_a_hang():
    device, fab = grbl_job()
    port = sim_port(device, "mute=1")
    with pytest.raises(StreamStopped, match="no GRBL banner .* even after a soft reset"):
        stream(port, fab.program, device, stall_timeout=1)
    assert port.written == b"\x18"  # the reset, and nothing of the program


def test_grbl_keeps_at_most_127_bytes_unacknowledged():
    device, fab = grbl_job()
    port = sim_port(device)
    run(port, fab.program, device)
    assert 100 < port.max_in_flight <= GRBL_RX_BUFFER
    assert port.simulator.stats.max_fill <= GRBL_RX_BUFFER


def test_grbl_error_stops_with_line_and_meaning():
    device, fab = grbl_job()
    port = sim_port(device, "error_at=40")
    with pytest.raises(StreamStopped) as stop:
        run(port, fab.program, device)
    line = fab.program.text.split("\n")[39]
    assert str(stop.value).startswith(f"GRBL error 20 at program line 40 ({line!r}): "
                                      "Unsupported or invalid g-code command found in block.")
    assert stop.value.lifted and not stop.value.cancelled
    assert b"!" in port.written and b"\x18" in port.written  # feed hold, then soft reset
    line_start = fab.program.text.index(line + "\n", sum(len(x) + 1 for x in fab.program.text.split("\n")[:39]) - 1)
    assert stop.value.acknowledged <= line_start


def test_grbl_m0_pause_holds_until_the_operator_answers_then_resumes_with_tilde():
    device, fab = grbl_job("two-sided")
    port = sim_port(device)
    asked = []

    def operator(message):
        sim = port.simulator
        asked.append((message, sim.frozen.copy(), bool(sim.planner)))
        return True

    stream(port, fab.program, device, operator=operator)
    (pause,) = fab.program.pauses
    assert asked == [(pause.message, {"hold"}, False)]  # held at M0, motion finished
    assert b"~" in port.written
    assert same_strokes(port.simulator.strokes, strokes_of(fab.program, device))
    assert [p.reason for p in port.simulator.stats.pauses] == ["M0"]


def test_grbl_alarm_stops_the_job_with_its_meaning():
    device, fab = grbl_job()
    port = ScriptedGrbl({12: "ALARM:1"})
    with pytest.raises(StreamStopped, match="GRBL alarm 1: Hard limit triggered") as stop:
        stream(port, fab.program, device)
    assert stop.value.lifted
    assert port.written.count(b"G0 Z3\n") >= 2  # the program's preamble again: tool up


# --- the host waits without spinning -------------------------------------------------------------


def test_host_cpu_stays_low_while_the_plotter_works(pty_plotter):
    """A plotter at its own speed on a pty: the host sleeps in blocking reads."""
    device, fab = grbl_job()
    path, proc, record = pty_plotter("grbl", time="real")
    port = open_port(path, device)
    cancel = threading.Event()
    timer = threading.Timer(4.0, cancel.set)
    wall, cpu = time.monotonic(), time.process_time()
    timer.start()
    try:
        with pytest.raises(StreamStopped, match="stopped on request"):
            stream(port, fab.program, device, cancel=cancel)
    finally:
        timer.cancel()
        port.close()
    share = (time.process_time() - cpu) / (time.monotonic() - wall)
    assert share < 0.05, f"the host used {share:.1%} of a core"
    stop_pty(proc, record)


@pytest.mark.parametrize("device_name, time_option", [
    ("hp7475a", "instant"), ("grbl", "instant"), ("hp7475a", "fast&speedup=10"), ("grbl", "fast&speedup=10"),
    ("graphtec-ce6000", "fast&speedup=10")])
def test_eta_is_on_the_clock_the_plotter_runs_on(device_name, time_option):
    """Issue 18: under sim://?time=fast the ETA mixed the simulated and the wall clock (1:12 at the
    start, 9.54 at 37 %, done after 1.6 s).  Elapsed time and ETA are both read on the plotter's
    clock, so the ETA at 37 % foretells the time the job then takes."""
    device = load_device(device_name)
    job = ROOT / "jobs" / "hexagon-fig8a.toml"
    design = load_design(job)
    program = fabricate(design, device, parse_fabrication(design.job.fabrication, str(job))).program
    events = []
    link = open_port(f"sim://{device_name}?time={time_option}", device)
    try:
        stream(link, program, device, events=events.append)
    finally:
        link.close()
    end = events[-1]
    assert end.kind == "done" and end.elapsed > 5  # seconds of the plotter's clock, not of the host's
    at = min((e for e in events if e.kind == "progress"), key=lambda e: abs(e.fraction - 0.37))
    assert 0.2 < at.fraction < 0.55, [round(e.fraction, 2) for e in events]
    taken = end.elapsed - at.elapsed
    assert at.eta == pytest.approx(taken, rel=0.3), (at.eta, taken)
    assert events[0].eta == pytest.approx(end.elapsed, rel=0.3), (events[0].eta, end.elapsed)
