"""What a simulated plotter records: statistics, and strokes as JSON or an SVG preview."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from foldfab.devices import DeviceProfile
    from foldfab.programs.machine import Stroke


@dataclass
class PauseRecord:
    """The device waited for the operator: held (GRBL ``M0``, ``!``) or parked (HPGL ``SP0``)."""

    start: float
    """Virtual seconds."""
    duration: float | None
    """None while it lasts."""
    reason: str


@dataclass
class JobRecord:
    """One job a device served: from its first byte of job data to its last command or move."""

    number: int
    start: float
    """Virtual seconds."""
    end: float
    received: int
    """Bytes received (queries between jobs count to the next job)."""
    drawn: float
    """mm drawn."""

    def line(self) -> str:
        """One line for ``foldfab sim``'s output."""
        return (f"job {self.number:<8} received {self.received} bytes, drew {self.drawn:.1f} mm in "
                f"{self.end - self.start:.2f} s")


@dataclass
class SimStats:
    """Counters and virtual times (seconds) of one simulated device."""

    bytes_received: int = 0
    """Every byte that reached the device, realtime and device-control bytes included."""
    bytes_lost: int = 0
    """Bytes dropped because the receive buffer was full (overrun)."""
    bytes_corrupted: int = 0
    """Bytes the ``noise`` option altered."""
    overruns: int = 0
    """Separate overrun episodes (runs of lost bytes)."""
    max_fill: int = 0
    """Peak receive-buffer fill, bytes."""
    commands: int = 0
    """HPGL instructions / G-code lines received complete."""
    errors: list[str] = field(default_factory=list)
    """Errors reported: ``error:N`` (GRBL), ``OE N`` / ``ESC.E N`` (HPGL)."""
    alarms: list[str] = field(default_factory=list)
    xoff_sent: int = 0
    xon_sent: int = 0
    busy_time: float = 0.0
    """Moving, lifting the pen or dwelling (for a complete program: the estimate, or a little
    more with junction speeds and a planner too short to look ahead as far as the estimate)."""
    starved_time: float = 0.0
    """Idle with nothing to execute while more of the job was still to come."""
    link_starved_time: float = 0.0
    """The part of ``starved_time`` when the host's wire carried nothing either: the host let the
    device wait (a round trip it waited on, or a host too slow to write), not the line's pace."""
    link_starvations: int = 0
    """How many times that happened."""
    paused_time: float = 0.0
    """Held or parked for the operator (see ``pauses``)."""
    stalled_time: float = 0.0
    first_byte: float | None = None
    """Virtual time the first byte of job data arrived (realtime and device-control bytes
    such as ``?`` or ``ESC.B`` are not job data)."""
    last_activity: float | None = None
    """Virtual time the last command or move finished."""
    pauses: list[PauseRecord] = field(default_factory=list)
    jobs: list[JobRecord] = field(default_factory=list)
    """Jobs ended so far (see :meth:`foldfab.sim.device.Simulator.end_job`)."""

    @property
    def plot_time(self) -> float:
        """From the first byte of job data to the end of the last move (virtual seconds); of
        each job, when jobs were recorded (the waits between them are nobody's time)."""
        if self.jobs:
            return sum(job.end - job.start for job in self.jobs)
        if self.first_byte is None or self.last_activity is None:
            return 0.0
        return max(0.0, self.last_activity - self.first_byte)

    def as_dict(self) -> dict:
        return dict(asdict(self), plot_time=self.plot_time)

    def summary(self) -> str:
        """Human-readable lines."""
        lines = [
            f"bytes        {self.bytes_received} received, {self.bytes_lost} lost "
            f"({self.overruns} overruns), {self.bytes_corrupted} corrupted, peak fill {self.max_fill}",
            f"commands     {self.commands}, errors {len(self.errors)}"
            + (f" ({', '.join(self.errors[:5])}{', ...' if len(self.errors) > 5 else ''})"
               if self.errors else "") + (f", alarms {', '.join(self.alarms)}" if self.alarms else ""),
            f"flow         {self.xoff_sent} XOFF, {self.xon_sent} XON",
            f"time         plot {self.plot_time:.2f} s: busy {self.busy_time:.2f} s, starved "
            f"{self.starved_time:.2f} s, paused {self.paused_time:.2f} s ({len(self.pauses)} pauses), "
            f"stalled {self.stalled_time:.2f} s",
        ]
        return "\n".join(lines)


def stroke_dict(stroke: Stroke) -> dict:
    return {"points": stroke.points.round(6).tolist(), "pen": stroke.pen, "force": stroke.force,
            "speed": stroke.speed, "pen_down": stroke.pen_down, "offset": stroke.offset,
            "power": stroke.power}


def layer_named(strokes: list[Stroke], device: DeviceProfile) -> list[Stroke]:
    """``strokes`` named by the device profile's layer whose tool drew them: the same pen (HPGL),
    force and lowered position (G-code) or power (a laser, to 6 decimals); layers with one tool share a name ("valley+mountain",
    the first one's colour).  A device receives no layer names, only tools; a stroke that no
    layer's tool drew keeps its "pen N" name (grey)."""
    from dataclasses import replace

    from foldfab.programs.program import Section
    from foldfab.devices import Tool

    by_tool: dict[tuple, list[str]] = {}
    for name, layer in device.layers.items():
        by_tool.setdefault((layer.pen if device.protocol != "gcode" else None, layer.force,
                            layer.pen_down, _rounded(layer.power)), []).append(name)
    named = []
    for stroke in strokes:
        names = by_tool.get((stroke.pen, stroke.force, stroke.pen_down, _rounded(stroke.power)))
        if names is None:
            named.append(stroke)
            continue
        section = Section(stroke.offset, 0, 0, "+".join(names), 0,
                          Tool(stroke.pen or 0, stroke.force, stroke.speed, 1, power=stroke.power))
        named.append(replace(stroke, section=section))
    return named


def _rounded(power: float | None) -> float | None:
    """A laser's power as the program's ``S`` words keep it (a share of ``$30``, 6 decimals)."""
    return None if power is None else round(power, 6)
