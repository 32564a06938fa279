"""Laser safety in the GRBL engine, on the simulated board: a board without laser mode ($32=0)
or with another $30 is refused before anything is sent; the end of a job, a cancel and a fault
leave the beam off (M5; a fault: feed hold, soft reset, then M5)."""

from __future__ import annotations

import threading
from dataclasses import replace

import pytest

from foldfab.devices import load_device
from foldfab.errors import FoldfabError
from foldfab.plotting.engines.base import StreamStopped
from foldfab.plotting.stream import stream
from helpers import ROOT
from helpers.plans import assert_round_trip
from helpers.streams import ScriptedGrbl, fabricated, same_strokes, sim_port, strokes_of

STAR = str(ROOT / "jobs" / "star.toml")


@pytest.fixture(scope="module")
def laser():
    return load_device("grbl-laser")


def after_last_reset(port) -> bytes:
    written = bytes(port.written)
    return written[written.rindex(b"\x18") + 1:]


def test_a_board_without_laser_mode_is_refused_before_anything_is_sent(laser):
    fab = fabricated(STAR, "grbl-laser")
    port = sim_port(laser, "laser_mode=0")
    with pytest.raises(FoldfabError, match=r"grbl-laser has \$32=0: GRBL's laser mode is off.*send \$32=1"):
        stream(port, fab.program, laser, operator=lambda message: True)
    assert b"$$\n" in port.written and b"M4" not in port.written and b"G1" not in port.written
    assert port.simulator.strokes == [] and port.simulator.beam is None


def test_a_board_whose_30_is_not_the_profiles_is_refused(laser):
    fab = fabricated(STAR, "grbl-laser")
    port = sim_port(laser)  # the board says $30=1000
    other = replace(laser, gcode=replace(laser.gcode, spindle_max=255.0))
    with pytest.raises(FoldfabError, match=r"reports \$30=1000 but its profile .* spindle_max = 255"):
        stream(port, fab.program, other, operator=lambda message: True)
    assert b"M4" not in port.written


def test_the_end_of_a_laser_job_leaves_the_beam_off_and_draws_each_power(laser):
    fab = fabricated(STAR, "grbl-laser", "two-sided")
    port = sim_port(laser)
    stream(port, fab.program, laser, operator=lambda message: True)
    sim = port.simulator
    assert sim.beam is None and not sim.stats.errors
    assert same_strokes(sim.strokes, strokes_of(fab.program, laser))
    assert {round(s.power, 6) for s in sim.strokes} == {0.15, 0.6}
    assert port.written.index(b"$$\n") < port.written.index(b"M4")
    assert fab.program.text.endswith("M5\nG0 X0 Y0\nM2\n")
    assert_round_trip(fab.plan, laser, fab.program)


class CancelWhileBurning:
    """A port that sets ``cancel`` once the simulated beam burns (M4, strokes drawn)."""

    def __init__(self, port, cancel: threading.Event):
        object.__setattr__(self, "_port", port)
        object.__setattr__(self, "cancel", cancel)
        object.__setattr__(self, "burnt", None)

    def __getattr__(self, name):
        return getattr(self._port, name)

    def __setattr__(self, name, value):
        setattr(self._port, name, value)

    def write(self, data):
        written = self._port.write(data)
        sim = self._port.simulator
        if sim.beam == "M4" and sim.strokes and not self.cancel.is_set():
            object.__setattr__(self, "burnt", len(sim.strokes))
            self.cancel.set()
        return written


def test_a_cancel_switches_the_beam_off(laser):
    fab = fabricated(STAR, "grbl-laser")
    cancel = threading.Event()
    port = CancelWhileBurning(sim_port(laser), cancel)
    with pytest.raises(StreamStopped, match="stopped on request") as stop:
        stream(port, fab.program, laser, cancel=cancel, operator=lambda message: True)
    assert stop.value.cancelled and stop.value.lifted
    assert 0 < port.burnt < len(strokes_of(fab.program, laser))  # cancelled while burning
    assert port.simulator.beam is None
    assert b"M5\n" in after_last_reset(port._port)


def test_a_fault_holds_resets_and_switches_the_beam_off(laser):
    fab = fabricated(STAR, "grbl-laser")
    first_g1 = fab.program.text[:fab.program.text.index("\nG1 ")].count("\n") + 1
    port = sim_port(laser, f"error_at={first_g1 + 6}")
    with pytest.raises(StreamStopped, match="GRBL error 20 at program line") as stop:
        stream(port, fab.program, laser, operator=lambda message: True)
    assert stop.value.lifted and not stop.value.cancelled
    written = bytes(port.written)
    hold, reset = written.rindex(b"!"), written.rindex(b"\x18")
    assert hold < reset and b"M4" in written[:hold]
    assert b"M5\n" in after_last_reset(port)
    assert port.simulator.beam is None and port.simulator.strokes


def test_a_laser_job_resumes_at_any_stroke_with_the_beam_on_at_its_power(laser):
    from foldfab.plotting.resume import resume_program

    fab = fabricated(STAR, "grbl-laser", "two-sided")
    strokes = strokes_of(fab.program, laser)
    for stroke in range(0, len(strokes), 7):
        resumed = resume_program(fab.program, laser, stroke)
        assert same_strokes(strokes_of(resumed, laser), strokes[stroke:])


@pytest.mark.parametrize("settings, error", [
    ([b"$30=1000", b"$31=0"], FoldfabError),
    ([b"$30=1000", b"$32=1x"], StreamStopped),
    ([b"$30=" + b"9" * 400, b"$32=1"], StreamStopped),
    ([b"$32=1"], FoldfabError),
    ([b"$30=255", b"$32=1"], FoldfabError),
])
def test_a_board_whose_settings_do_not_say_laser_mode_and_30_is_refused(laser, settings, error):
    fab = fabricated(STAR, "grbl-laser")
    board = ScriptedGrbl({}, tuple(settings))
    with pytest.raises(error) as refused:
        stream(board, fab.program, laser, operator=lambda message: True)
    assert "\n" not in str(refused.value)
    assert any(word in str(refused.value) for word in ("$32", "$30", "unreadable setting"))
    assert b"M4" not in board.written and b"G1" not in board.written


@pytest.mark.parametrize("fault, options, message", [
    ("cancel", "", "stopped on request"),
    ("error", "error_at=40", "GRBL error 20"),
    ("disconnect", "disconnect_after=3000", "disconnected|did not answer|lost"),
])
def test_a_stopped_laser_job_resumes_on_a_fresh_board_and_burns_the_rest_at_its_power(laser, fault, options, message):
    """End to end on the simulated board: the stop leaves the beam off (where the board can still
    be reached), and the resume burns exactly the strokes not yet burnt, each at its layer's power."""
    import re

    from helpers.resumes import leading_matches, stop_and_resume

    program = fabricated(str(ROOT / "jobs" / "vase-svg.toml"), "grbl-laser").program
    stop, port, second, index, want = stop_and_resume(
        laser, program, options, cancel_after=6000 if fault == "cancel" else None)
    assert re.search(message, str(stop)), str(stop)
    if fault != "disconnect":
        assert port.simulator.beam is None  # off: M5 (after a feed hold and reset on a fault)
    assert 0 < index < len(want)
    assert index <= leading_matches(port.simulator.strokes, want), "a stroke would be lost"
    assert same_strokes(second.strokes, want[index:])
    assert [s.power for s in second.strokes] == [s.power for s in want[index:]]
    assert second.beam is None  # the end of the resumed job switches it off too
