"""Streaming to the simulated plotters: fabrications of the example jobs, ports on ``sim://``
wrapped in a :class:`Spy`, the strokes a program draws, and the HP 7475A set to XON/XOFF."""

from __future__ import annotations

import functools
import re
from collections import deque
from pathlib import Path

import numpy as np
import pytest

from foldfab.design import load_design
from foldfab.devices import load_device
from foldfab.fabricate import fabricate
from foldfab.fabrication.spec import parse_fabrication
from foldfab.plotting.transport import open_port
from foldfab.programs.interpret import interpret
from helpers import ROOT


FLOWS = {"hp7475a": "escb", "graphtec-ce6000": "rtscts", "roland-gx24": "none", "grbl": "grbl", "grbl-laser": "grbl"}
SIM = "sim://?time=instant&sheet=A3"
FAST_BAUD = 115200
"""Host and simulated wire run at this rate where a test is about correctness, not timing:
short virtual times, and few pacing waits for the XON/XOFF and RTS/CTS senders."""


def xonxoff_profile(folder: Path) -> Path:
    """The HP 7475A set to XON/XOFF (its other handshake), as a profile file."""
    text = (ROOT / "devices" / "hp7475a.toml").read_text()
    text = text.replace('name = "hp7475a"', 'name = "hp7475a-xonxoff"')
    text = text.replace("xonxoff = false", "xonxoff = true")
    text = re.sub(r'flow_control = "escb".*', 'flow_control = "xonxoff"', text)
    path = folder / "hp7475a-xonxoff.toml"
    path.write_text(text)
    return path


def instant_motion(name: str | Path, folder: Path) -> Path:
    """A copy of a profile (a built-in's name, or a path) whose motion takes no time at all:
    on it the link is the only limit."""
    source = Path(name) if Path(name).suffix == ".toml" else ROOT / "devices" / f"{name}.toml"
    text = source.read_text()
    text = re.sub(r"(?ms)^\[limits\]\n.*?(?=^\[)", "", text)
    text = re.sub(r"(?m)^(draw_speed|travel_speed|speed|z_speed) = .*$", r"\1 = 100000", text)
    text = re.sub(r"(?m)^acceleration = .*$", "acceleration = 1000000000", text)
    text = re.sub(r"(?m)^pen_lift_time = .*$", "pen_lift_time = 0", text)
    path = folder / f"{source.stem}-instant.toml"
    path.write_text(text)
    return path


def device_for(name: str, xonxoff_device: str):
    return load_device(xonxoff_device if name == "xonxoff" else name)


@functools.lru_cache(maxsize=None)
def fabricated(job: str, device: str, strategy: str = "force"):
    """The fabrication of ``job`` on ``device`` (A3, scale 0.4: every example job fits, but one
    made to be split, which is fitted whole)."""
    from helpers.plans import whole

    spec = parse_fabrication({"sheet": "A3", "margin": 5, "scale": 0.4, "strategy": strategy, **whole(job)}, "test")
    return fabricate(load_design(job), load_device(device), spec)


def strokes_of(program, device):
    return interpret(program, device, (297.0, 420.0)).strokes


def same_strokes(got, want, atol: float = 1e-6) -> bool:
    """Same strokes in the same order: points, tool, force, speed, a laser's power."""
    return len(got) == len(want) and all(
        a.points.shape == b.points.shape and np.allclose(a.points, b.points, atol=atol)
        and (a.pen, a.force, a.pen_down, a.power) == (b.pen, b.force, b.pen_down, b.power)
        and a.speed == pytest.approx(b.speed) for a, b in zip(got, want))


class Spy:
    """A port that checks every write is ``bytes`` and counts GRBL's unacknowledged bytes."""

    def __init__(self, port, grbl: bool = False):
        object.__setattr__(self, "_port", port)
        object.__setattr__(self, "_grbl", grbl)
        object.__setattr__(self, "written", bytearray())
        object.__setattr__(self, "_lines", deque())
        object.__setattr__(self, "_replies", bytearray())
        object.__setattr__(self, "max_in_flight", 0)

    def __getattr__(self, name):
        return getattr(self._port, name)

    def __setattr__(self, name, value):
        setattr(self._port, name, value)

    def write(self, data):
        assert type(data) is bytes, f"wrote {type(data).__name__}, not bytes"
        self.written.extend(data)
        if self._grbl:
            if data == b"\x18":
                self._lines.clear()
            elif data not in (b"?", b"!", b"~"):
                self._lines.extend(len(line) + 1 for line in data.split(b"\n")[:-1])
                object.__setattr__(self, "max_in_flight", max(self.max_in_flight, sum(self._lines)))
        return self._port.write(data)

    def read(self, size=1):
        data = self._port.read(size)
        if self._grbl:
            self._replies.extend(data)
            *lines, rest = re.split(rb"[\r\n]", bytes(self._replies))  # "ok\r" is a whole answer
            self._replies[:] = rest
            for line in lines:
                if (line == b"ok" or line.startswith(b"error:")) and self._lines:
                    self._lines.popleft()
        return data


def sim_port(device, options: str = "", baudrate: int | None = None, **kw) -> Spy:
    port = open_port(f"{SIM}&{options}" if options else SIM, device, baudrate=baudrate, **kw)
    return Spy(port, grbl=device.protocol == "gcode")


class ScriptedGrbl:
    """A tiny fake GRBL board: banner, ``ok`` per line, status, a scripted reply at some lines
    (counted from 1) and ``settings`` lines as its answer to ``$$``."""

    def __init__(self, reply_at: dict[int, str], settings: tuple[bytes, ...] = ()):
        self.reply_at, self.lines, self.settings = reply_at, 0, settings
        self.out = bytearray(b"Grbl 1.1h ['$' for help]\r\n")
        self.timeout, self.baudrate, self.bytesize, self.parity, self.stopbits = 1.0, 115200, 8, "N", 1
        self.xonxoff = self.rtscts = False
        self.written, self.line = bytearray(), bytearray()

    @property
    def in_waiting(self):
        return len(self.out)

    def read(self, size=1):
        data = bytes(self.out[:size])
        del self.out[:size]
        return data

    def write(self, data):
        assert type(data) is bytes
        self.written += data
        for byte in data:
            if byte == ord("?"):
                self.out += b"<Idle|MPos:0.000,0.000,3.000|FS:0,0>\r\n"
            elif byte == 0x18:
                self.out += b"Grbl 1.1h ['$' for help]\r\n"
            elif byte == ord("\n"):
                self.lines += 1
                if self.line == b"$$":
                    self.out += b"".join(line + b"\r\n" for line in self.settings)
                self.out += (self.reply_at.get(self.lines, "ok") + "\r\n").encode()
                self.line.clear()
            else:
                self.line.append(byte)
        return len(data)


def send_status(port, data: bytes, chunk: int = 1024) -> None:
    """GP-GL pacing as the open drivers do it: a chunk cut after a command, then ESC 0x05 until "0"
    (the polls 50 ms apart: a read that expects nothing)."""
    sent = 0
    while sent < len(data):
        end = data.rfind(b"\x03", sent, sent + chunk) + 1 or len(data)
        port.write(data[sent:end])
        sent = end
        while True:
            port.write(b"\x1b\x05")
            if port.read_until(b"\x03") == b"0\x03":
                break
            timeout, port.timeout = port.timeout, 0.05
            assert port.read(1) == b""
            port.timeout = timeout
