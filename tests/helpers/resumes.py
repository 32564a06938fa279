"""Stopping and resuming on the simulated plotters: the device for each flow control, a job on
one, and how many strokes a recording has of the program's."""

from __future__ import annotations

import numpy as np

from helpers import ROOT
from helpers.streams import device_for, fabricated


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
