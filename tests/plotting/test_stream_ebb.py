"""The EBB engine against the simulated EiBotBoard: every job on both AxiDraw profiles, "done" only
once the motors are idle, a cancel that stops at once with the pen up and the carriage home, the
board's faults, and resumes that complete the drawing."""

from __future__ import annotations

import re
import threading

import pytest

from foldfab.design import load_design
from foldfab.devices import load_device
from foldfab.fabricate import fabricate
from foldfab.plotting.engines.base import StreamStopped
from foldfab.plotting.resume import resume_program
from foldfab.plotting.stream import locate_pen, stream
from foldfab.plotting.transport import open_port
from foldfab.programs.interpret import interpret
from helpers import JOBS, ROOT
from helpers.plans import spec
from helpers.resumes import leading_matches, stop_and_resume
from helpers.streams import FAST_BAUD, Spy, same_strokes

AXIDRAWS = ["axidraw-v3", "axidraw-se-a3"]
SHEETS = {"axidraw-v3": "A4 landscape", "axidraw-se-a3": "A3 landscape"}
VASE = ROOT / "jobs" / "vase-svg.toml"


def fabricated(job, name: str):
    return fabricate(load_design(job), load_device(name), spec(sheet=SHEETS[name], scale="fit"))


def port_for(device, options: str = "") -> Spy:
    """A sim:// port on the profile's sheet, ``options`` a query (default ``time=instant``)."""
    sheet = SHEETS[device.name].replace(" ", "%20")
    url = f"sim://?sheet={sheet}&" + (options or "time=instant")
    return Spy(open_port(url, device, baudrate=FAST_BAUD))


def wanted(program, device):
    return interpret(program, device).strokes


@pytest.mark.parametrize("name", AXIDRAWS)
@pytest.mark.parametrize("job", JOBS, ids=[j.stem for j in JOBS])
def test_every_job_plots_on_both_axidraws(job, name):
    """The board draws exactly the program's strokes, answers every command OK, and when the
    sender says done the motors are idle and the pen is up at home."""
    device = load_device(name)
    program = fabricated(job, name).program
    port = port_for(device)
    events = []
    result = stream(port, program, device, events=events.append, operator=lambda m: True)
    sim = port.simulator
    assert not sim.stats.errors and sim.stats.bytes_lost == 0
    assert same_strokes(sim.strokes, wanted(program, device))
    assert result.sent == len(program.text)
    assert not sim.planner and sim.block_end is None, "done while the board still moved"
    assert sim.machine.stroke is None and sim.machine.motors == [0, 0]
    acked = [e.acknowledged for e in events]
    assert acked == sorted(acked) and events[-1].kind == "done" and events[-1].fraction == 1.0
    # the sender's own words: V first, then the program command by command, QM at the end
    written = bytes(port.written)
    assert written.startswith(b"V\r") and written.endswith(b"QM\r")
    assert written[2:].replace(b"QM\r", b"") == program.encode()


def test_done_waits_for_the_motors_to_stop():
    """The last OK comes when the last move enters the FIFO: the sender asks QM until idle."""
    device = load_device("axidraw-v3")
    program = fabricated(ROOT / "jobs" / "hexagon-fig8a.toml", "axidraw-v3").program
    port = port_for(device)
    seen = []
    stream(port, program, device, events=lambda e: seen.append((e.kind, port.simulator.t)))
    sim = port.simulator
    busy_end = sim.stats.last_activity
    assert seen[-1][0] == "done" and seen[-1][1] >= busy_end
    assert bytes(port.written).count(b"QM\r") >= 2  # asked while it still moved, then idle


def test_pauses_wait_for_the_motors_then_ask_the_operator():
    device = load_device("axidraw-se-a3")
    job = fabricate(load_design(ROOT / "jobs" / "star.toml"), device,
                    spec(sheet=SHEETS[device.name], scale="fit", strategy="two-sided"))
    program = job.program
    (pause,) = program.pauses
    port = port_for(device)
    asked = []

    def operator(message):
        sim = port.simulator
        asked.append((message, bool(sim.planner), sim.machine.stroke is None, len(sim.strokes)))
        return True
    stream(port, program, device, operator=operator)
    before = sum(s.offset < pause.offset for s in wanted(program, device))
    assert asked == [(pause.message, False, True, before)]
    assert same_strokes(port.simulator.strokes, wanted(program, device))


@pytest.mark.parametrize("fault, options, message", [
    ("cancel", "", "stopped on request"),
    ("error", "error_at=300", r"answered '!8 Err: injected fault' to 'S[MP],"),
    ("disconnect", "disconnect_after=6000", "serial link to axidraw-v3 failed: .*device disconnected"),
    ("noise", "noise=0.003&seed=3", "answered .!8 Err|did not answer"),
])
def test_a_stop_lifts_the_pen_homes_and_the_resume_completes_the_drawing(fault, options, message):
    device = load_device("axidraw-v3")
    program = fabricated(VASE, "axidraw-v3").program
    stop, port, second, index, want = stop_and_resume(
        device, program, options, cancel_after=6000 if fault == "cancel" else None, ports=port_for)
    first = port.simulator
    assert re.search(message, str(stop)), str(stop)
    assert stop.cancelled == (fault == "cancel")
    if fault != "disconnect":  # ES, pen up, home
        assert stop.lifted and first.machine.stroke is None and first.machine.motors == [0, 0]
    assert (fault == "noise" or 0 < index) and index < len(want)
    assert same_strokes(second.strokes, want[index:])
    if fault != "noise":  # a flipped digit may make a valid command that moves elsewhere
        assert index <= leading_matches(first.strokes, want), "a stroke would be lost"


def test_a_cancel_stops_the_motors_at_once():
    """ES ends the move in progress: the board is still within the few moves in flight."""
    device = load_device("axidraw-v3")
    program = fabricated(VASE, "axidraw-v3").program
    port = port_for(device)
    cancel, at = threading.Event(), []
    write = port._port.write

    def counting(data):
        if len(port.written) > 6000 and not cancel.is_set():
            cancel.set()
            at.append(port.simulator.t)
        return write(data)
    port._port.write = counting
    with pytest.raises(StreamStopped):
        stream(port, program, device, cancel=cancel)
    sim = port.simulator
    written = bytes(port.written)
    assert re.search(rb"\rES\rSP,1,\d+\rHM,\d+\r$", written), written[-40:]
    sim.run_until_idle()
    # after the cancel: at most the slices in flight, the pen up and the trip home
    home = max(abs(m) for m in sim.machine.motors)  # zero: it got there
    assert home == 0 and sim.stats.last_activity - at[0] < 8.0


@pytest.mark.parametrize("options, words", [
    ("mute=1", "did not answer its version"),
    ("stall=200&stall_at=3000", "did not answer"),
])
def test_a_silent_board_is_a_clear_fault(options, words):
    device = load_device("axidraw-v3")
    program = fabricated(VASE, "axidraw-v3").program
    port = port_for(device, f"time=fast&{options}")
    with pytest.raises(StreamStopped, match=words):
        stream(port, program, device, stall_timeout=1.0)


def test_a_port_that_is_not_an_ebb_is_refused():
    """The HP 7475A simulator does not answer V with an EBB version."""
    device = load_device("axidraw-v3")
    program = fabricated(VASE, "axidraw-v3").program
    hp = open_port("sim://hp7475a?time=instant", load_device("hp7475a"))
    with pytest.raises(StreamStopped, match="did not answer its version|not an EBB version"):
        stream(hp, program, device, stall_timeout=1.0)


def test_locate_says_the_position_is_unknown():
    device = load_device("axidraw-v3")
    assert locate_pen(port_for(device), device) is None


@pytest.mark.parametrize("name", AXIDRAWS)
@pytest.mark.parametrize("job", JOBS, ids=[j.stem for j in JOBS])
def test_resume_program_draws_exactly_the_remaining_strokes(job, name):
    """From home (HM), the setup, a pen-up move to the stroke, then the program from its SP,0."""
    device = load_device(name)
    program = fabricated(job, name).program
    strokes = wanted(program, device)
    for index in sorted({0, 1, len(strokes) // 2, len(strokes) - 1}):
        resumed = resume_program(program, device, index)
        assert resumed.text.startswith("SP,1,150\rHM,")
        assert resumed.text.endswith(program.text[strokes[index].offset:])
        assert same_strokes(wanted(resumed, device), strokes[index:]), index
