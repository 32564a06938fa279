"""G-code writer for GRBL 1.1 plotters and drag knives.

One block per line, ``\\n`` endings, every line shorter than 80 characters (GRBL's
line buffer), numbers with at most three decimals, and only words GRBL 1.1 accepts:
``G0 G1 G4 G17 G21 G90 M0 M2 M3 M4 M5`` with ``X Y Z F S P``.  Modal ``G1`` and ``F``
are written only when they change.  The tool goes up and down either by Z moves
(``G0 Z<up>`` / ``G1 Z<down> F<z feed>``) or by servo commands (``M3 S..`` /
``M5``, each followed by a ``G4 P<pen_lift_time>`` dwell), as the profile says.

A laser (``[gcode] tool = "laser"``, GRBL's laser mode ``$32=1``) has no Z moves: ``M4 S0``
once switches dynamic power on, each stroke is a ``G0`` to its start (the beam is off on
rapids) and ``G1`` moves whose first carries the layer's power as an ``S`` word when it
changes (``power`` times ``$30``, the profile's ``spindle_max``); ``M5`` switches the beam
off at every pause and at the end.  A dot (a one-point line) is left out: in ``M4`` the beam
burns only while the head moves.

A pause (sheet flip, or a tool change on a device without a pen changer) lifts the
tool, parks it, writes the operator message as ``(comment)`` lines (GRBL strips
comments) and then ``M0``; the message is also in :attr:`Program.pauses`.  The end
lifts the tool, parks it and writes ``M2``.

vpype-gcode templates are not used: they have no per-layer tool depth, no pauses,
and they do not refuse geometry outside the machine's reach.
"""

from __future__ import annotations

import functools
import re
import textwrap
from typing import TYPE_CHECKING

import numpy as np

from foldfab.devices import GCODE_DECIMALS
from foldfab.errors import FoldfabError
from foldfab.programs.program import Program, ProgramBuilder, Sink, Stop, Sweep, fmt_number, sweeps

if TYPE_CHECKING:
    from foldfab.devices import DeviceProfile
    from foldfab.fabrication.plan import PlotPlan

MAX_LINE = 79  # characters before "\n": GRBL 1.1 holds 80 including the terminator


def round_as_text(values: np.ndarray, decimals: int) -> np.ndarray:
    """``values`` rounded to ``decimals`` places as ``"%.*f"`` writes them: correctly, from each
    binary value.  ``np.round`` scales first, and the product can land on a tie the value itself
    is above (0.0005 is written 0.001 but ``np.round`` gives 0.0), so near ties the text decides."""
    scaled = values * 10.0 ** decimals
    rounded = np.round(values, decimals)
    near = np.abs(scaled - np.floor(scaled) - 0.5) < 1e-6
    if near.any():
        rounded[near] = [float("%.*f" % (decimals, v)) for v in values[near].tolist()]
    return rounded


def write_gcode(plan: PlotPlan, device: DeviceProfile, sink: Sink | None = None) -> Program:
    """The GRBL 1.1 program drawing ``plan`` on ``device``;
    ``sink``: see :class:`~foldfab.programs.program.ProgramBuilder` (the text streamed, not kept)."""
    items = sweeps(plan, device)
    out = _GcodeWriter(device, sink)
    sheet = f"{fmt_number(plan.sheet[0], 1)} x {fmt_number(plan.sheet[1], 1)} mm"
    out.comment(f"foldfab program for {device.name}, sheet {sheet}")
    out.line("G21 G90 G17")
    out.pen_up()
    for item in items:
        if isinstance(item, Stop):
            out.park()
            for text in textwrap.wrap(_ascii(item.message), MAX_LINE - 2) or [""]:
                out.comment(text)
            out.line("M0")
            out.builder.pause(item)
        else:
            out.sweep(item)
    out.park()
    out.line("M2")
    return out.builder.build()


def _xy_words(points: np.ndarray) -> list[str]:
    """``"X.. Y.."`` for each row of ``points`` (mm), each number as :func:`fmt_number` writes
    it: all of them formatted by one ``%`` and trimmed by three substitutions over the text."""
    number = f"%.{GCODE_DECIMALS}f"
    text = (f"X{number} Y{number}\n" * len(points)) % tuple(points.ravel().tolist())
    text = _ZEROS.sub(r"\1", text)        # "12.300" -> "12.3", "12.000" -> "12."
    text = _POINT.sub("", text)           # "12." -> "12"
    text = _MINUS_ZERO.sub("0", text)     # "-0" (a small negative number rounded) -> "0"
    return text.split("\n")[:-1]


_ZEROS = re.compile(r"(\.\d*?)0+(?=[ \n])")
_POINT = re.compile(r"\.(?=[ \n])")
_MINUS_ZERO = re.compile(r"(?<=[XY])-0(?=[ \n])")


def _ascii(text: str) -> str:
    """Comment-safe text: printable ASCII, no parentheses (GRBL ends a comment at ')')."""
    text = text.translate({ord("("): "[", ord(")"): "]"})
    return "".join(c if " " <= c <= "~" else ("?" if c > "~" else " ") for c in text)


class _GcodeWriter:
    """Writes lines and tracks GRBL's modal state (motion mode, feed, tool up/down)."""

    def __init__(self, device: DeviceProfile, sink: Sink | None = None):
        self.device = device
        self.builder = ProgramBuilder("gcode", device, record=True, sink=sink)
        self.motion: str | None = None
        self.feed: float | None = None
        self.position: str | None = None  # "X.. Y.." of the last move
        self.down = True  # unknown at the start: force the first lift
        self.power: str | None = None  # a laser's modal S value
        self.number = functools.cache(functools.partial(fmt_number, decimals=GCODE_DECIMALS))
        """Text of a feed, Z height or dwell: the same few values recur at every stroke."""

    def line(self, text: str) -> None:
        assert len(text) <= MAX_LINE, text
        self.builder.write(text + "\n")

    def comment(self, text: str) -> None:
        self.line("(" + _ascii(text)[: MAX_LINE - 2] + ")")

    def move(self, mode: str, words: str, feed: float | None = None, power: str | None = None) -> None:
        """One G0/G1 block with modal words omitted when unchanged (``power``: a laser's S value)."""
        head = "" if mode == self.motion else mode + " "
        tail = ""
        if feed is not None and feed != self.feed:
            tail = " F" + self.number(feed)
            self.feed = feed
        if power is not None and power != self.power:
            tail += " S" + power
            self.power = power
        self.motion = mode
        self.line(head + words + tail)

    def pen_command(self, command: str) -> None:
        self.line(command)
        if self.device.motion.pen_lift_time > 0:
            self.line("G4 P" + self.number(self.device.motion.pen_lift_time))

    def pen_up(self) -> None:
        if not self.down:
            return
        up = self.device.gcode.pen_up
        if self.device.laser:
            self.line("M5")
        elif isinstance(up, str):
            self.pen_command(up)
        else:
            self.move("G0", "Z" + self.number(up))
        self.down = False

    def pen_down(self, down: float | str | None) -> None:
        if self.device.laser:  # M4 once: between strokes, G0 moves keep the beam off
            if not self.down:
                self.line("M4 S0")
                self.power = "0"
        elif isinstance(down, str):
            self.pen_command(down)
        else:
            self.move("G1", "Z" + self.number(down), self.device.gcode.z_speed * 60)
        self.down = True

    def travel(self, xy: str) -> None:
        if xy != self.position:
            self.move("G0", xy)
            self.position = xy

    def park(self) -> None:
        self.pen_up()
        park = np.asarray([self.device.motion.park])
        self.travel(_xy_words(park)[0])
        self.builder.recorder.move(tuple(round_as_text(park[0], GCODE_DECIMALS).tolist()))

    def sweep(self, sweep: Sweep) -> None:
        self.builder.start(sweep)
        self.comment(f"{sweep.name} pass, tool {sweep.tool.pen}, sweep {sweep.repeat + 1} "
                     f"of {sweep.tool.passes}")
        if not self.device.laser and sweep.tool.pen_down is None and sweep.name not in self.device.layers:
            raise FoldfabError(
                f"plan step {sweep.step + 1}: {self.device.name} has no [layers.{sweep.name}] "
                f"table to say how deep the tool goes (known: {', '.join(self.device.layers)}); "
                f"add one to {self.device.source} or rename the pass"
            )
        down = (None if self.device.laser  # a beam has no depth: its power is the tool's
                else sweep.tool.pen_down if sweep.tool.pen_down is not None else self.device.layers[sweep.name].pen_down)
        feed = sweep.tool.speed * 60
        power = self.number(sweep.tool.power * self.device.gcode.spindle_max) if self.device.laser else None
        drawn = np.repeat(sweep.sizes > 1, sweep.sizes) if self.device.laser else slice(None)
        # as the text gives them: rounded to its decimals, the speed as its F word
        self.builder.recorder.strokes(round_as_text(sweep.points[drawn], GCODE_DECIMALS),
                                      sweep.sizes[sweep.sizes > 1] if self.device.laser else sweep.sizes,
                                      float(self.number(feed)) / 60, sweep.name)
        for batch, sizes in sweep.batches():   # the words of a batch of lines at a time
            self._lines(_xy_words(batch), sizes.tolist(), down, feed, power)

    def _lines(self, words: list[str], sizes: list[int], down, feed: float, power: str | None) -> None:
        """Lines of ``sizes`` points, their ``"X.. Y.."`` ``words`` one after another."""
        start = 0
        for size in sizes:
            points = words[start:start + size]
            start += size
            if self.device.laser:
                if len(points) == 1:
                    continue  # a laser burns only while it moves (M4): it has no dots
                self.position = None  # a G0 even where the head is: each stroke is its own
            self.travel(points[0])
            self.pen_down(down)
            if len(points) > 1:
                self.move("G1", points[1], feed, power)
            if len(points) > 2:  # G1 and F are modal: the rest are bare coordinates
                self.builder.write("\n".join(points[2:]) + "\n")
            self.position = points[-1]
            self.builder.recorder.ended(self.builder.offset)  # the next command lifts the tool
            if not self.device.laser:
                self.pen_up()
