"""The fault matrix of the USB transports: stop a job on a simulated device behind one, let the
device finish what it holds, resume on a fresh one and compare both recordings with the program."""

from __future__ import annotations

import threading
from typing import Callable

import pytest

from foldfab.plotting.engines.base import StreamStopped
from foldfab.plotting.progress import JobProgress
from foldfab.plotting.resume import resume_program
from foldfab.plotting.stream import stream
from helpers.resumes import leading_matches
from helpers.streams import Spy, same_strokes, strokes_of

FAULTS = {
    # fault: (simulator options, paper out after, the message expected)
    "cancel": ("time=instant", None, "stopped on request"),
    "unplug": ("time=instant&disconnect_after=3000", None, "device disconnected"),
    # hung for good (instant time would run through any stall at once)
    "stall": ("time=fast&stall=1e9&stall_at=3000", None, "did not answer OE|took no data"),
    # a printer device says so; on raw USB the cutter just takes nothing (the protocol's status tells)
    "paper-out": ("time=instant", 3000, "paper out: load the sheet|took no data for .* an empty tray"),
    # a GP-GL cutter's own status (ESC 0x05 answers 2): the sheet came out
    "tray-empty": ("time=instant&unload_at=3000", None, "tray empty"),
}


def stop_and_resume(device, fab, fault: str, opened: Callable[[str, int | None], tuple]):
    """Run the job until ``fault`` stops it, then resume on a fresh device.

    ``opened(options, paper_out_after)`` gives (port, simulator, close) for a simulated
    device behind the transport.  Returns (the stop, the first simulator, the second's
    strokes, the stroke the resume starts at, the program's strokes)."""
    options, paper_out, _ = FAULTS[fault]
    port, first, close = opened(options, paper_out)
    spy = Spy(port)
    cancel = threading.Event()
    if fault == "cancel":
        write = port.write

        def counting(data):
            if len(spy.written) > 3000:
                cancel.set()
            return write(data)
        object.__setattr__(spy, "_port", _Wrapped(port, counting))
    try:
        with pytest.raises(StreamStopped) as stopped:
            stream(spy, fab.program, device, cancel=cancel, operator=lambda m: True, stall_timeout=1.0)
    finally:
        close()
    if fault == "stall":  # the operator clears the jam: the cutter runs on, at once (instant time)
        from foldfab.sim.clock import Clock

        first.clock = Clock("instant")
        first.clock.sleep_until(first.t)
    first.run_until_idle()  # the device finishes whatever it still holds
    stop = stopped.value
    want = strokes_of(fab.program, device)
    index = JobProgress(fab.program, device).strokes_done(stop.acknowledged)
    port, second, close = opened("time=instant", None)
    try:
        if index < len(want):
            stream(port, resume_program(fab.program, device, index, stop.pauses_done), device,
                   operator=lambda m: True)
    finally:
        close()
    return stop, first, second.strokes, index, want


def check_stop(fault: str, stop, first, second, index, want) -> None:
    """The message names the fault, the tool is up, the resume draws exactly the rest and
    nothing before it was left undrawn."""
    import re

    assert re.search(FAULTS[fault][2], str(stop)), str(stop)
    assert stop.cancelled == (fault == "cancel")
    if fault == "stall":  # the lift could not be confirmed: the message says so; the PU it sent is held
        assert stop.lifted or "lift it by hand" in str(stop)
        assert first.machine.stroke is None  # and done once the cutter runs again
    elif fault in ("unplug", "paper-out"):  # the device takes nothing more: the tool may be down
        assert not stop.lifted
    else:  # the tool is up once the device has done what it held
        assert first.machine.stroke is None
    assert same_strokes(second, want[index:])
    assert leading_matches(first.strokes, want) >= index
    if fault == "cancel":
        assert stop.lifted


class _Wrapped:
    """A port whose ``write`` is replaced (the rest passes through)."""

    def __init__(self, port, write):
        object.__setattr__(self, "_port", port)
        object.__setattr__(self, "write", write)

    def __getattr__(self, name):
        return getattr(self._port, name)

    def __setattr__(self, name, value):
        setattr(self._port, name, value)
