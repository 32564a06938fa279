"""Resuming where the plotter really stopped: a plotter whose host was lost goes on drawing
what it holds; before resuming foldfab asks where its pen is.

The invariant: the stroke foldfab resumes at is never beyond the first stroke not drawn
(no stroke lost), and is exactly that stroke when the pen's stop state (position and pen
up or down) occurs once in the part of the program the plotter may have run; then only
the interrupted stroke is drawn twice.
"""

from __future__ import annotations

import itertools
import threading

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from foldfab.devices import load_device
from foldfab.errors import FoldfabError
from foldfab.programs.read_gcode import GcodeMachine
from foldfab.programs.read_hpgl import HPGLMachine, HPGLTokenizer
from foldfab.plotting.progress import JobProgress
from foldfab.plotting.resume import (PlotStopped, ResumeAmbiguous, first_undrawn, load_state, locate, locate_resume,
                            plot, resume_program)
from foldfab.plotting.engines.base import PenPosition, StreamStopped
from foldfab.plotting.stream import locate_pen, stream
from foldfab.plotting.transport import open_port
from helpers import JOBS, ROOT
from helpers.resumes import FLOWS, job_for, leading_matches
from helpers.streams import FAST_BAUD, device_for, fabricated, strokes_of

HPGL_FLOWS = ["escb", "rtscts", "none", "xonxoff"]


def same_points(got, want) -> bool:
    return len(got) == len(want) and all(
        a.points.shape == b.points.shape and np.allclose(a.points, b.points) for a, b in zip(got, want))


_session = itertools.count()


def steps(program, device):
    """(end offset, step) for each step a plotter takes: HP-GL coordinate pairs and
    instructions, G-code lines; and the machine that executes them."""
    frame = device.frame((297.0, 420.0))
    if program.protocol == "hpgl":
        tokenizer = HPGLTokenizer(split_coordinates=True)
        commands = tokenizer.feed(program.encode()) + tokenizer.close()
        machine = HPGLMachine(device, frame, None)
        return machine, [(end, lambda c=c: machine.execute(c)) for c, end in
                         zip(commands, [c.offset for c in commands[1:]] + [len(program.text)])]
    machine, out, offset = GcodeMachine(device, frame, None), [], 0
    for raw in program.text.split("\n"):
        end = min(offset + len(raw) + 1, len(program.text))
        out.append((end, lambda raw=raw, o=offset, e=end: machine.execute(raw, o, e)))
        offset = end
    return machine, out


def states(program, device):
    """After each step: (end offset, (x, y, pen down), strokes drawn), positions rounded to
    the device's resolution.

    Computed independently of :func:`first_undrawn`: a stroke counts as drawn once the
    machine has lifted it or stands on its last point."""
    strokes = strokes_of(program, device)
    machine, todo = steps(program, device)
    digits = 0 if program.protocol == "hpgl" else 3
    out = []
    for end, step in todo:
        step()
        x, y = machine.position
        lifted = len(machine.result.strokes)
        drawn = lifted + bool(machine.stroke is not None and lifted < len(strokes)
                              and len(machine.stroke) == len(strokes[lifted].points)
                              and np.allclose(machine.frame.to_sheet(machine.stroke), strokes[lifted].points))
        out.append((end, (round(x, digits), round(y, digits), machine.stroke is not None), drawn))
    return out


def unique_stop(table, start_stroke: int, stop: int) -> bool:
    """Does the state at index ``stop`` occur only once from where ``start_stroke`` may begin?"""
    first = next(i for i, (_, _, drawn) in enumerate(table) if drawn >= start_stroke)
    return [state for _, state, _ in table[max(first - 1, 0):stop + 1]].count(table[stop][1]) == 1


@settings(max_examples=60, deadline=None)
@given(data=st.data(), job=st.sampled_from([j for j in JOBS if j.stem != "vase-svg"]),
       name=st.sampled_from(["hp7475a", "graphtec-ce6000", "roland-gx24", "grbl"]))
def test_first_undrawn_never_skips_a_stroke_and_is_exact_when_the_stop_is_unambiguous(data, job, name):
    device = load_device(name)
    program = fabricated(str(job), name).program
    strokes = strokes_of(program, device)
    table = states(program, device)
    stop = data.draw(st.integers(0, len(table) - 1), label="stop")
    end, (x, y, down), drawn = table[stop]
    if drawn >= len(strokes):
        return
    acked = data.draw(st.integers(0, drawn), label="acknowledged stroke")
    found = first_undrawn(program, device, strokes, acked, PenPosition(x, y, down), len(program.text))
    assert found is not None and acked <= found <= drawn
    if unique_stop(table, acked, stop):
        assert found == drawn
    # a limit before the stop hides it: the answer is an earlier state or none, never beyond
    hidden = first_undrawn(program, device, strokes, acked, PenPosition(x, y, down), end - 1)
    assert hidden is None or hidden <= drawn


def test_a_position_the_program_never_reaches_says_nothing():
    device = load_device("hp7475a")
    program = fabricated(str(ROOT / "jobs/star.toml"), "hp7475a").program
    strokes = strokes_of(program, device)
    assert first_undrawn(program, device, strokes, 3, PenPosition(-777, 12345, True), len(program.text)) is None


def replug(device, fab, cut: int, drain: bool, options: str = ""):
    """Stream until the cable is pulled after ``cut`` bytes; optionally let the plotter draw what
    it holds; plug the cable back in, locate the pen and resume.  Returns the acknowledged
    stroke, the located one, the plotter, its state when located (x, y, pen down) and the note."""
    session = f"replug{next(_session)}"
    url = f"sim://?time=instant&sheet=A3&session={session}{options}"
    port = open_port(f"{url}&disconnect_after={cut}", device, baudrate=FAST_BAUD)
    with pytest.raises(StreamStopped) as stopped:
        stream(port, fab.program, device)
    plotter = port.simulator
    if drain:
        plotter.run_until_idle()
    acked = JobProgress(fab.program, device).strokes_done(stopped.value.acknowledged)
    located, note = locate_resume(fab.program, device, url, acked, 0, baudrate=FAST_BAUD)
    x, y = plotter.machine.position
    stop = (round(x), round(y), plotter.machine.stroke is not None)
    again = open_port(url, device, baudrate=FAST_BAUD)
    assert again.simulator is plotter
    stream(again, resume_program(fab.program, device, located, 0), device)
    return acked, located, plotter, stop, note


@pytest.mark.parametrize("drain", [False, True], ids=["replugged-at-once", "replugged-after-it-stopped"])
@pytest.mark.parametrize("flow", HPGL_FLOWS)
def test_a_replugged_plotter_resumes_at_the_first_stroke_it_did_not_draw(flow, drain, xonxoff_device):
    device, fab = job_for(FLOWS[flow], xonxoff_device)
    want = strokes_of(fab.program, device)
    table = states(fab.program, device)
    for cut in (1500, 3001, 4444):
        acked, located, plotter, stop, note = replug(device, fab, cut, drain)
        drawn = plotter.strokes
        first_run = drawn[:len(drawn) - (len(want) - located)]
        assert same_points(drawn[len(first_run):], want[located:])  # the resume draws exactly the rest
        complete = leading_matches(first_run, want)
        assert len(first_run) - complete <= 1, "the first run drew a stroke that is not the program's"
        if len(first_run) > complete:  # the interrupted stroke: the start of the program's
            part, whole = first_run[-1].points, want[complete].points
            assert len(part) < len(whole) and np.allclose(part, whole[:len(part)])
        assert acked <= located <= complete, "a stroke would be lost"
        index = next(i for i, (_, state, done) in enumerate(table) if state == stop and done == complete)
        assert unique_stop(table, acked, index)  # the sender kept the pen states in flight unique
        assert located == complete, (cut, acked, located, note)  # only the interrupted one again
        assert "more stroke(s) after the last acknowledgement" in note, note


@pytest.mark.parametrize("flow", HPGL_FLOWS)
def test_a_replugged_plotter_is_located_exactly_where_its_pen_revisits_points(flow, xonxoff_device):
    """The star's creases meet at shared vertices, so the same pen state comes back within a few
    strokes.  With inline markers the sender never lets the plotter hold such a repeat while the
    earlier one may still be unacknowledged: cut anywhere, the resume starts exactly at the
    stroke the plotter was drawing."""
    device = device_for(FLOWS[flow], xonxoff_device)
    fab = fabricated(str(ROOT / "jobs/star.toml"), xonxoff_device if flow == "xonxoff" else FLOWS[flow])
    want = strokes_of(fab.program, device)
    table = states(fab.program, device)
    repeats = [i for i in range(len(table)) if not unique_stop(table, 0, i)]
    assert len(repeats) > 10  # the job does revisit points
    for cut in range(500, len(fab.program.text) - 100, 41):
        for drain in (False, True):
            acked, located, plotter, stop, note = replug(device, fab, cut, drain)
            drawn = plotter.strokes
            first_run = drawn[:len(drawn) - (len(want) - located)]
            complete = leading_matches(first_run, want)
            assert same_points(drawn[len(first_run):], want[located:])
            assert located == complete, (cut, drain, acked, located, complete, note)


def test_a_plotter_switched_off_and_on_is_not_trusted():
    """A fresh plotter (initialized, pen at the origin) says nothing about the job: resume at the
    last acknowledged stroke."""
    device = load_device("hp7475a")
    program = fabricated(str(ROOT / "jobs/star.toml"), "hp7475a").program
    stroke, note = locate_resume(program, device, "sim://?time=instant", 5, 0)
    assert stroke == 5 and note.startswith("the plotter was initialized since it stopped")
    port = open_port("sim://?time=instant", device)
    port.simulator.machine.position = (100.0, 200.0)
    port.write(b"OS;")  # the engine's first checkpoint reads OS: "initialized" is cleared
    assert port.read_until(b"\r") == b"24\r"
    assert locate_pen(port, device) == PenPosition(100, 200, False)


@pytest.mark.parametrize("drain", [False, True], ids=["replugged-at-once", "replugged-after-it-stopped"])
def test_a_grbl_board_that_does_not_reset_on_opening_is_located(drain):
    """A board behind a bridge that does not reset it (reset_on_open=0) keeps its position: it
    finishes what it holds, a soft reset at rest clears a line the cable cut, and its status
    gives the position."""
    device, fab = job_for("grbl", None)
    want = strokes_of(fab.program, device)
    acked, located, plotter, stop, note = replug(device, fab, 1500, drain, "&reset_on_open=0")
    drawn = [s for s in plotter.strokes if s.length > 0]  # the tool resting through the reset: a dot
    first_run = drawn[:len(drawn) - (len(want) - located)]
    assert same_points(drawn[len(first_run):], want[located:])
    complete = leading_matches(first_run, want)
    assert len(first_run) - complete <= 1
    assert acked < located == complete, note  # GRBL held more than it had acknowledged
    assert "more stroke(s) after the last acknowledgement" in note


def test_a_grbl_board_that_resets_on_opening_is_not_trusted():
    device = load_device("grbl")
    program = fabricated(str(ROOT / "jobs/star.toml"), "grbl").program
    stroke, note = locate_resume(program, device, "sim://?time=instant", 5, 0)
    assert stroke == 5 and note.startswith("the plotter was initialized since it stopped")
    assert locate_pen(open_port("sim://?time=instant", device), device) is None


def test_an_unreachable_plotter_leaves_the_acknowledged_stroke():
    device = load_device("hp7475a")
    program = fabricated(str(ROOT / "jobs/star.toml"), "hp7475a").program
    stroke, note = locate_resume(program, device, "/dev/nonexistent-plotter", 4, 0)
    assert stroke == 4 and note.startswith("could not ask the plotter where it stopped")


@pytest.mark.parametrize("name", ["hp7475a", "grbl"])
def test_after_a_plotter_error_its_position_is_not_used(name, tmp_path, monkeypatch):
    """The plotter skipped the instruction it reported, then went on: its position lies past a
    stroke it did not draw correctly.  The resume starts at the last acknowledged stroke."""
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path))
    device = load_device(name)
    job = str(ROOT / "jobs/vase-svg.toml")
    program = fabricated(job, name).program
    session = f"error{next(_session)}"
    url = f"sim://?time=instant&sheet=A3&session={session}&reset_on_open=0"
    with pytest.raises(PlotStopped) as stopped:
        plot(program, device, job=job, port=f"{url}&error_at=100")
    assert stopped.value.stop.plotter_error
    state = load_state(stopped.value.token)
    assert not state.locate
    events = []
    plot(program, device, job=job, port=url, resume=state.token, events=events.append)
    assert "the plotter reported an error, so where it stopped is not used" in events[0].message
    assert events[0].message.startswith(f"resuming at stroke {state.stroke + 1} of")


def test_a_cancelled_or_cut_plot_may_be_located(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path))
    device = load_device("hp7475a")
    job = str(ROOT / "jobs/vase-svg.toml")
    program = fabricated(job, "hp7475a").program
    with pytest.raises(PlotStopped) as stopped:
        plot(program, device, job=job, port="sim://?time=instant&sheet=A3&disconnect_after=3000")
    assert not stopped.value.stop.plotter_error and load_state(stopped.value.token).locate


def test_a_grbl_board_left_in_a_feed_hold_is_located_and_unlocked():
    """A stop whose lifting was itself interrupted (Ctrl-C twice) leaves the board in a feed hold.
    The hold has come to rest, so the position is kept: the resume asks it, resets the board,
    unlocks the ALARM:3 GRBL raises at a reset in a hold (as the stop's own lift does), and
    finishes the job, no stroke lost."""
    device, fab = job_for("grbl", None)
    want = strokes_of(fab.program, device)
    url = "sim://?time=instant&sheet=A3&session=held-board&reset_on_open=0"
    with pytest.raises(StreamStopped) as stopped:
        stream(open_port(f"{url}&disconnect_after=1500", device, baudrate=FAST_BAUD), fab.program, device)
    held = open_port(url, device, baudrate=FAST_BAUD)
    plotter = held.simulator
    held.write(b"!")
    held.close()
    assert plotter._status().startswith("<Hold:0|")
    acked = JobProgress(fab.program, device).strokes_done(stopped.value.acknowledged)
    located, note = locate_resume(fab.program, device, url, acked, 0, baudrate=FAST_BAUD)
    assert not note.startswith("could not ask"), note
    assert plotter._status().startswith("<Idle|") and plotter.stats.alarms == ["ALARM:3"]
    assert acked <= located
    stream(open_port(url, device, baudrate=FAST_BAUD), resume_program(fab.program, device, located, 0), device)
    drawn = [s for s in plotter.strokes if s.length > 0]
    assert same_points(drawn[len(drawn) - (len(want) - located):], want[located:])
    assert leading_matches(drawn[:len(drawn) - (len(want) - located)], want) >= located


# --- a plotter switched off and on between the fault and the resume --------------------------------

HEXAGON = str(ROOT / "jobs/hexagon-fig8a.toml")  # 28 strokes: the job
POWER_CYCLED = [(flow, "") for flow in HPGL_FLOWS] + [("grbl", "&reset_on_open=0"), ("grbl", "&reset_on_open=1")]


def session_plotter(session: str):
    from foldfab.plotting.urlhandler.protocol_sim import _SESSIONS

    return _SESSIONS[session]


def cancel_after(count: int, cancel: threading.Event, monkeypatch) -> None:
    """Ctrl-C once the plotter has received ``count`` bytes (of the ports plot() opens)."""
    import foldfab.plotting.transport

    real = foldfab.plotting.transport.open_port

    def counting(url, device, **kw):
        port = real(url, device, **kw)
        write = port.write
        port.write = lambda data: (port.simulator.stats.bytes_received >= count and cancel.set(), write(data))[1]
        return port
    monkeypatch.setattr(foldfab.plotting.transport, "open_port", counting)


def drawn_strokes(plotter) -> list:
    return [s for s in plotter.strokes if s.length > 0]  # (a GRBL tool resting through a reset: a dot)


@pytest.mark.parametrize("fault", ["disconnect", "cancel"])
@pytest.mark.parametrize("flow, board", POWER_CYCLED, ids=[f"{f}{b.replace('&', '-')}" for f, b in POWER_CYCLED])
def test_a_plotter_switched_off_and_on_after_a_fault_is_never_taken_for_done(flow, board, fault, xonxoff_device,
                                                                            tmp_path, monkeypatch):
    """The cable is pulled (or the plot cancelled), the plotter switched off and on (at the origin,
    pen up, holding nothing; a GRBL board behind a bridge that does not reset it does not even
    greet), then the job resumed.  Its position is also where the job parks at its end: that is no
    proof the job is done.  The resume either starts where nothing is lost, or stops with its token
    kept and the choice for the operator; choosing the last acknowledged stroke finishes the drawing."""
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path))
    device, fab = job_for(FLOWS[flow], xonxoff_device, job=HEXAGON)
    want = strokes_of(fab.program, device)
    ambiguous = 0
    for cut in (len(fab.program.text) // 4, len(fab.program.text) // 2):
        session = f"cycled{next(_session)}"
        url = f"sim://?time=instant&sheet=A3&session={session}{board}"
        cancel = threading.Event()
        if fault == "cancel":
            cancel_after(cut, cancel, monkeypatch)
        with pytest.raises(PlotStopped) as stopped:
            plot(fab.program, device, job=HEXAGON, baudrate=FAST_BAUD, cancel=cancel,
                 port=f"{url}&power_cycle=1" + (f"&disconnect_after={cut}" if fault == "disconnect" else ""))
        monkeypatch.undo()
        monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path))
        first, token = session_plotter(session), stopped.value.token
        acked = load_state(token).stroke
        try:
            plot(fab.program, device, job=HEXAGON, port=url, resume=token, baudrate=FAST_BAUD)
        except ResumeAmbiguous as doubt:
            ambiguous += 1
            where = doubt.location
            assert (where.acknowledged, where.strokes) == (acked, len(want)) and where.stroke > acked
            assert "switched off and on" in str(doubt) and load_state(token).stroke == acked  # token kept
            asked = []
            plot(fab.program, device, job=HEXAGON, port=url, resume=token, baudrate=FAST_BAUD,
                 choose=lambda location: asked.append(location) or location.acknowledged)
            assert asked == [where]
        second = session_plotter(session)
        assert second is not first  # switched off and on
        resumed = drawn_strokes(second)
        start = len(want) - len(resumed)
        assert start <= leading_matches(drawn_strokes(first), want), "strokes left undrawn"
        assert same_points(resumed, want[start:]) and start >= acked
        with pytest.raises(FoldfabError, match="no saved plot with that token"):
            load_state(token)  # finished: deleted
    if board == "&reset_on_open=0" and fault == "disconnect":
        assert ambiguous == 2  # (the issue: a board that does not greet, at the origin, pen up)


@pytest.mark.parametrize("name", ["hp7475a", "grbl"])
def test_a_position_at_the_end_of_the_program_is_not_taken_for_done(name):
    """A plotter that really parked at the end and one that was reset look the same; either way the
    queue worker (nobody to ask) resumes at the last acknowledged stroke, and :func:`locate` says why."""
    device = load_device(name)
    program = fabricated(HEXAGON, name).program
    url = f"sim://?time=instant&sheet=A3&session=parked{next(_session)}&reset_on_open=0"
    port = open_port(url, device, baudrate=FAST_BAUD)
    stream(port, program, device)  # the whole job: the plotter parks at the origin, pen up
    port.simulator.run_until_idle()
    if name == "hp7475a":
        port = open_port(url, device, baudrate=FAST_BAUD)
        port.write(b"OS;")  # (the job's IN set "initialized": read it, as the engine does)
        port.read_until(b"\r")
    found = locate(program, device, url, 20, 0, baudrate=FAST_BAUD)
    assert (found.acknowledged, found.stroke, found.safe) == (20, 28, 20)
    assert "finished the job on its own" in found.doubt and "switched off and on" in found.doubt
    assert locate_resume(program, device, url, 20, 0, baudrate=FAST_BAUD)[0] == 20
