"""Simulator options: the query of a ``sim://`` URL or ``foldfab sim --option key=value``.

Every option, its type and meaning (the fault options describe what a test provokes):

=====================  ================================================================
``time``               ``real`` (default), ``fast`` (the virtual clock runs ``speedup``
                       times the wall clock) or ``instant`` (only blocking host calls
                       move it; on a pty, the device runs ahead while the host is silent)
``speedup``            ``fast`` only: how many virtual seconds per wall second (50)
``sheet``              sheet the strokes are reported on: ``A3``, ``A4 landscape``,
                       ``297x420`` (default: the profile's)
``flow``               the device's handshake instead of the profile's ``[buffer]
                       flow_control``: ``xonxoff``, ``rtscts``, ``escb``, ``grbl``, ``none``
``buffer``             receive buffer bytes instead of the profile's ``[buffer] size``
``planner``            GRBL planner blocks (16; one is always kept free, as in GRBL)
``reset_on_open``      GRBL: 1 (default) the board resets and prints its banner when the
                       port opens (Arduino DTR reset); 0 it stays silent until a soft reset
``laser_mode``         GRBL's ``$32``: 1 laser mode (the default for a laser profile: G0 moves
                       switch the beam off, power changes on moves do not stop motion), 0 a
                       spindle board (the default for other profiles: the beam stays on while
                       M3/M4 are, rapids included, and every power change stops motion)
``disconnect_after``   after the device received that many bytes the cable is pulled
``error_at``           GRBL: line N answers ``error:<error_code>`` and is not executed;
                       HPGL: instruction N is not executed and sets ``OE`` to ``error_code``
``error_code``         default 20 for GRBL ("unsupported or invalid g-code command", what a
                       line garbled in transit gives), 1 for HPGL ("instruction not recognized")
``noise``              probability that a received byte has one bit flipped
``seed``               random seed of ``noise`` (0)
``stall``              seconds the device stops consuming and answering, once
``stall_at``           received byte count that starts the stall (default: four buffers)
``mute``               1: the device never answers: no banner, replies, XON; CTS low
``unload_at``          GP-GL: after the device received that many bytes its sheet comes out
                       (0: none is loaded): it lifts the tool, stops, and answers status
                       ``2`` (tray empty)
``power_cycle``        1: the plotter is switched off and on once the first port to it has
                       closed or lost its cable: the next open finds a fresh one (at the
                       origin, pen up, holding nothing, initialized; a GRBL board greets
                       only with ``reset_on_open``), with this setup (time, sheet, flow,
                       buffer, planner, reset_on_open) and no fault options; with
                       ``session``, or a simulator given to the port
``session``            ``sim://`` only: ports opened with the same session name in one
                       process share one plotter, as when a cable is unplugged and plugged
                       back in (the first open creates it; later opens ignore the other
                       options)
=====================  ================================================================
"""

from __future__ import annotations

import re
from dataclasses import dataclass, fields, replace
from typing import Iterable

from foldfab.devices import FLOW_CONTROLS, parse_sheet
from foldfab.errors import FoldfabError, unknown_key

TIME_MODES = ("real", "fast", "instant")


@dataclass(frozen=True)
class SimOptions:
    """Validated simulator options (see the module docstring)."""

    time: str = "real"
    speedup: float = 50.0
    sheet: tuple[float, float] | None = None
    flow: str | None = None
    buffer: int | None = None
    planner: int = 16
    reset_on_open: bool = True
    laser_mode: bool | None = None
    disconnect_after: int | None = None
    error_at: int | None = None
    error_code: int | None = None
    noise: float = 0.0
    seed: int = 0
    stall: float = 0.0
    stall_at: int | None = None
    mute: bool = False
    unload_at: int | None = None
    power_cycle: bool = False
    session: str | None = None

    FAULTS = ("disconnect_after", "error_at", "error_code", "noise", "seed", "stall", "stall_at",
              "mute", "unload_at", "power_cycle")
    """What a test provokes (spent when the plotter is switched off and on: ``power_cycle``)."""

    def switched_on(self) -> SimOptions:
        """These options without the faults: the plotter after ``power_cycle``."""
        return replace(self, **{name: getattr(SimOptions, name) for name in self.FAULTS})

    def as_dict(self) -> dict:
        """The options that differ from the defaults, for reports."""
        default = SimOptions()
        return {f.name: getattr(self, f.name) for f in fields(self)
                if getattr(self, f.name) != getattr(default, f.name)}


def _count(lo: int):
    def parse(text: str) -> int | None:
        return int(text) if re.fullmatch(r"\d+", text) and int(text) >= lo else None
    return parse


def _seconds(text: str) -> float | None:
    try:
        value = float(text)
    except ValueError:
        return None
    return value if 0 <= value < float("inf") else None


def _probability(text: str) -> float | None:
    value = _seconds(text)
    return value if value is not None and value <= 1 else None


def _flag(text: str) -> bool | None:
    return {"1": True, "true": True, "yes": True, "0": False, "false": False, "no": False}.get(
        text.lower())


def _sheet(text: str) -> tuple[float, float] | None:
    match = re.fullmatch(r"(\d+(?:\.\d*)?)\s*[xX]\s*(\d+(?:\.\d*)?)", text)
    return parse_sheet([float(match.group(1)), float(match.group(2))] if match else text)


_PARSERS = {
    "time": ("real, fast or instant", lambda t: t if t in TIME_MODES else None),
    "speedup": ("a number >= 1", lambda t: v if (v := _seconds(t)) is not None and v >= 1 else None),
    "sheet": ('A4, A3, Letter (+ " landscape") or WxH in mm', _sheet),
    "flow": (", ".join(FLOW_CONTROLS), lambda t: t if t in FLOW_CONTROLS else None),
    "buffer": ("a byte count >= 2", _count(2)),
    "planner": ("a block count >= 2", _count(2)),
    "reset_on_open": ("0 or 1", _flag),
    "laser_mode": ("0 or 1", _flag),
    "disconnect_after": ("a byte count", _count(0)),
    "error_at": ("a line or instruction number >= 1", _count(1)),
    "error_code": ("an error number >= 1", _count(1)),
    "noise": ("a probability 0..1", _probability),
    "seed": ("an integer >= 0", _count(0)),
    "stall": ("seconds >= 0", _seconds),
    "stall_at": ("a byte count", _count(0)),
    "mute": ("0 or 1", _flag),
    "unload_at": ("a byte count", _count(0)),
    "power_cycle": ("0 or 1", _flag),
    "session": ("a name of letters, digits, '.', '_' or '-'",
                lambda t: t if re.fullmatch(r"[\w.-]+", t) else None),
}


def parse_options(pairs: Iterable[tuple[str, str]], where: str = "simulator") -> SimOptions:
    """Options from (key, text) pairs; a FoldfabError names ``where``, the key and what it takes."""
    values: dict = {}
    for key, text in pairs:
        found = unknown_key([key], _PARSERS)
        if found:
            raise FoldfabError(f"{where}: unknown option {key!r}; {found[1]}")
        expected, parse = _PARSERS[key]
        value = parse(text.strip())
        if value is None:
            raise FoldfabError(f"{where}: option {key}={text!r}: expected {expected}")
        values[key] = value
    return SimOptions(**values)
