"""Stopping and resuming on the simulated plotters: the device for each flow control, a job on
one, and how many strokes a recording has of the program's."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from foldfab.plotting.engines.base import StreamStopped
from foldfab.plotting.progress import JobProgress
from foldfab.plotting.resume import resume_program
from foldfab.plotting.stream import stream
from helpers import ROOT
from helpers.streams import FAST_BAUD, device_for, fabricated, sim_port, strokes_of


FLOWS = {"escb": "hp7475a", "rtscts": "graphtec-ce6000", "none": "roland-gx24", "grbl": "grbl",
         "xonxoff": "xonxoff"}
VASE = str(ROOT / "jobs/vase-svg.toml")


def job_for(name, xonxoff_device, job=VASE, strategy="force"):
    device = device_for(name, xonxoff_device)
    return device, fabricated(job, xonxoff_device if name == "xonxoff" else name, strategy)


def leading_matches(drawn, wanted) -> int:
    """How many strokes at the start of ``drawn`` are the program's: exactly, except that the
    last may go on (an HP-GL error that skips the pen-up after a stroke extends it)."""
    count = 0
    for got, want in zip(drawn, wanted):
        if len(got.points) < len(want.points) or \
                not np.allclose(got.points[:len(want.points)], want.points, atol=1e-6):
            break
        count += 1
        if len(got.points) > len(want.points):
            break
    return count


def stop_and_resume(device, fab, options: str, cancel_after: int | None = None, stall_timeout=1.0,
                    time="instant"):
    """Run 1 until it stops; let the plotter finish what it holds; resume on a fresh plotter."""
    port = sim_port(device, f"time={time}&{options}", baudrate=FAST_BAUD)
    cancel = threading.Event()
    if cancel_after is not None:
        write = port._port.write

        def counting(data):
            if len(port.written) > cancel_after:
                cancel.set()
            return write(data)
        port._port.write = counting
    with pytest.raises(StreamStopped) as stopped:
        stream(port, fab.program, device, cancel=cancel, operator=lambda m: True,
               stall_timeout=stall_timeout)
    first = port.simulator
    first.run_until_idle()  # the plotter finishes whatever it still holds
    stop = stopped.value
    want = strokes_of(fab.program, device)
    index = JobProgress(fab.program, device).strokes_done(stop.acknowledged)
    second = sim_port(device, baudrate=FAST_BAUD)
    if index < len(want):
        stream(second, resume_program(fab.program, device, index, stop.pauses_done), device,
               operator=lambda m: True)
    return stop, port, second.simulator, index, want
