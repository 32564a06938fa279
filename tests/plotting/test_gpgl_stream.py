"""Streaming GP-GL: chunks paced by status polls, done only when the cutter is ready, and the
faults (cancel, stall, tray empty, a pulled cable, a mute cutter): a clear message, the tool up,
a resume that completes the drawing."""

from __future__ import annotations

import json
import re

import pytest

from foldfab.cli import main
from foldfab.design import load_design
from foldfab.fabricate import fabricate
from foldfab.devices import load_device
from foldfab.plotting.engines.base import StreamStopped
from foldfab.plotting.engines.gpgl import CHUNK
from foldfab.plotting.progress import JobProgress
from foldfab.plotting.stream import locate_pen, stream
from foldfab.errors import FoldfabError
from helpers import GPGL_DEVICES, HEXAGON, JOBS
from helpers import resumes
from helpers.resumes import leading_matches
from helpers.streams import fabricated, same_strokes, sim_port, strokes_of

CAMEO = "silhouette-cameo-4"
VASE = str(JOBS[-1])  # vase-svg: 400 strokes, several chunks


@pytest.mark.parametrize("name", GPGL_DEVICES)
def test_the_whole_job_is_drawn_and_done_means_the_cutter_has_stopped(name):
    device = load_device(name)
    fab = fabricated(VASE, name)
    port = sim_port(device, "time=instant")
    sim = port.simulator
    result = stream(port, fab.program, device)
    assert sim.status() == "0" and not sim.planner and sim.block_end is None  # not run_until_idle: at once
    assert result.sent == len(fab.program.text) and sim.stats.bytes_lost == 0
    assert same_strokes(sim.strokes, strokes_of(fab.program, device))
    assert sim.stats.max_fill <= device.buffer.size


def test_chunks_end_after_whole_commands_and_each_waits_for_ready():
    device = load_device(CAMEO)
    fab = fabricated(VASE, CAMEO)
    port = sim_port(device, "time=instant")
    chunks = []
    write = port._port.write

    def record(data):
        if data != b"\x1b\x05":
            assert port.simulator.status() == "0", "a chunk was sent before the cutter was ready"
            chunks.append(data)
        return write(data)
    port._port.write = record
    stream(port, fab.program, device)
    assert b"".join(chunks) == fab.program.encode() and len(chunks) > 10
    assert all(len(c) <= CHUNK and c.endswith((b"\x03", b"\x1b\x04")) for c in chunks)
    ends = set(JobProgress(fab.program, device).ends)
    offsets = [sum(map(len, chunks[:i + 1])) for i in range(len(chunks) - 1)]
    assert sum(o in ends for o in offsets) >= 0.9 * len(offsets)  # cut where a stroke ends


def stop_and_resume(options: str, cancel_after: int | None = None, time="instant"):
    """The Cameo 4 drawing the vase stopped, then resumed on a fresh cutter."""
    device = load_device(CAMEO)
    stop, port, second, index, want = resumes.stop_and_resume(device, fabricated(VASE, CAMEO).program, options, cancel_after,
                                                              time=time)
    return stop, port.simulator, second, index, want


def strokes_in_a_chunk(want, start: int) -> int:
    """The most strokes with bytes in one chunk from byte ``start``."""
    return sum(s.end > start and s.offset < start + CHUNK for s in want)


@pytest.mark.parametrize("fault, options, message", [
    ("cancel", "", "stopped on request"),
    ("stall", "stall=150&stall_at=3000", "did not answer the status request \\(ESC 0x05\\) within 1 s"),
    ("tray", "unload_at=3000", "reports its tray empty \\(status 2\\): the sheet came out or none is loaded; "
                               "load it as it was and resume; what it still held was discarded"),
    ("disconnect", "disconnect_after=3000", "serial link to silhouette-cameo-4 failed: .*device disconnected"),
])
def test_a_fault_stops_with_a_clear_message_the_tool_up_and_an_exact_resume(fault, options, message):
    stop, first, second, index, want = stop_and_resume(
        options, cancel_after=3000 if fault == "cancel" else None, time="fast" if fault == "stall" else "instant")
    assert re.search(message, str(stop)), str(stop)
    assert stop.cancelled == (fault == "cancel")
    assert stop.lifted == (fault != "disconnect")  # a pulled cable: nobody to tell (foldfab says so)
    assert (first.machine.stroke is None) == stop.lifted  # the tool is up
    assert same_strokes(second.strokes, want[index:])  # the resume draws exactly the rest ...
    drawn = leading_matches(first.strokes, want)
    assert index <= drawn  # ... and nothing before it was left undrawn
    twice = sum(s.length > 0 for s in first.strokes) - index
    if fault in ("cancel", "stall"):  # the cutter finished its chunk, then lifted the tool: exact
        assert twice <= 1 and index == drawn
    else:  # how far into its chunk it got, the cutter cannot say: at most that chunk again
        assert twice <= strokes_in_a_chunk(want, want[index].offset)


def test_a_cutter_without_a_sheet_stops_before_anything_is_sent():
    device = load_device(CAMEO)
    port = sim_port(device, "time=instant&unload_at=0")
    with pytest.raises(StreamStopped, match="tray empty") as stopped:
        stream(port, fabricated(str(HEXAGON), CAMEO).program, device)
    assert stopped.value.lifted and stopped.value.acknowledged == 0
    assert port.written == b"\x1b\x05"  # only the question


def test_a_mute_cutter_is_named_not_waited_for():
    device = load_device(CAMEO)
    port = sim_port(device, "time=instant&mute=1")
    with pytest.raises(StreamStopped, match="did not answer the status request"):
        stream(port, fabricated(str(HEXAGON), CAMEO).program, device, stall_timeout=1.0)


def test_a_cutter_that_keeps_moving_is_stalled():
    """A cutter that answers "moving" long after the estimate says it is done."""
    device = load_device(CAMEO)
    port = sim_port(device, "time=instant")
    port.simulator.status = lambda: "1"
    with pytest.raises(StreamStopped, match="stalled: still moving"):
        stream(port, fabricated(str(HEXAGON), CAMEO).program, device, stall_timeout=0.5)


def test_gpgl_cutters_cannot_say_where_they_stopped():
    device = load_device(CAMEO)
    with pytest.raises(FoldfabError, match="GP-GL, which has no position report"):
        locate_pen(sim_port(device, "time=instant"), device)


def test_foldfab_plot_draws_the_hexagon_on_the_simulated_cameo(capsys, tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    code = main(["plot", str(HEXAGON), "--device", CAMEO, "--port", "sim://silhouette-cameo-4?time=instant", "--json"])
    out = capsys.readouterr().out
    summary = json.loads([line for line in out.splitlines() if '"summary"' in line][0])
    device = load_device(CAMEO)
    program = fabricate(load_design(HEXAGON), device).program
    assert code == 0 and summary["drawn_mm"] == pytest.approx(sum(s.length for s in strokes_of(program, device)), abs=0.1)
    assert summary["pen_lifts"] == len(strokes_of(program, device))


def test_foldfab_plot_after_the_tray_empties_says_how_to_resume_and_the_resume_finishes(capsys, tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    port = "sim://silhouette-cameo-4?time=instant&unload_at=600"
    code = main(["plot", str(HEXAGON), "--device", CAMEO, "--port", port, "--yes"])
    err = capsys.readouterr().err
    assert code == 2 and "tray empty" in err and "tool lifted" in err and "Traceback" not in err
    token = re.search(r"--resume ([0-9a-f]+)", err).group(1)
    code = main(["plot", str(HEXAGON), "--device", CAMEO, "--port", "sim://silhouette-cameo-4?time=instant",
                 "--yes", "--resume", token])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "could not ask the plotter where it stopped" in out + err and "no position report" in out + err
