"""Job progress: what the plotter has done, in millimetres, layers and seconds.

The streaming engines (:mod:`foldfab.plotting.engines`) know byte offsets: how much of the
program the plotter has acknowledged (executed, counted conservatively).
:class:`JobProgress` turns an offset into what a person wants to see: drawn length
done out of the total (from the interpreted strokes and their byte offsets), the
current layer (the program's sections), elapsed time, and an ETA from
:mod:`foldfab.programs.estimate`.

Three reporters print :class:`ProgressEvent` objects: a one-line bar redrawn in place
on a terminal, plain lines every few seconds when stdout is a file or a pipe, and
one JSON object per line for scripts (``foldfab plot --json``).
"""

from __future__ import annotations

import bisect
import json
import time
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Callable, TextIO

if TYPE_CHECKING:
    from foldfab.devices import DeviceProfile
    from foldfab.programs.machine import Interpretation
    from foldfab.programs.program import Program


@dataclass(frozen=True)
class ProgressEvent:
    """One report of a running job (lengths in mm, times in seconds)."""

    kind: str
    """start | progress | pause (waiting for the operator) | resume | done | stopped"""
    acknowledged: int
    """Program bytes the plotter has executed (a conservative count)."""
    sent: int
    """Program bytes written to the port."""
    total: int
    """Program bytes."""
    drawn: float
    drawn_total: float
    strokes_done: int
    strokes_total: int
    layer: str
    """Layer being drawn at the acknowledged offset ("setup" before the first one)."""
    elapsed: float
    """Seconds since the job started, on the clock the plotter runs on (a ``sim://`` simulator's
    virtual clock, else the wall clock: :func:`foldfab.plotting.engines.base.plotter_clock`)."""
    eta: float
    """Seconds left on the same clock: the estimate of what remains, scaled by how fast the job
    has gone so far."""
    message: str = ""

    @property
    def fraction(self) -> float:
        """Part of the drawn length done (bytes when nothing is drawn)."""
        return done_share(self.drawn, self.drawn_total, self.acknowledged, self.total)

    def as_dict(self) -> dict:
        data = asdict(self)
        for key in ("drawn", "drawn_total", "elapsed", "eta"):
            data[key] = round(data[key], 2)
        data["percent"] = round(100 * self.fraction, 1)
        return data


def done_share(drawn: float, drawn_total: float, acknowledged: int, total: int) -> float:
    """How much of a job is done, 0..1: the share of its drawn length, as progress displays and
    the queue's list show it; the share of its bytes when it draws nothing (or its drawn length
    is not known)."""
    if drawn_total > 0:
        return min(drawn / drawn_total, 1.0)
    return min(acknowledged / total, 1.0) if total else 1.0


class JobProgress:
    """Maps acknowledged byte offsets of ``program`` to drawn length, layer and ETA."""

    def __init__(self, program: Program, device: DeviceProfile, run: Interpretation | None = None):
        from foldfab.programs.estimate import estimate
        from foldfab.programs.interpret import interpret
        from foldfab.programs.machine import Interpretation

        self.program = program
        run = run if run is not None else interpret(program, device)
        self.strokes = run.strokes
        self.starts = [s.offset for s in self.strokes]
        self.ends = [s.end for s in self.strokes]
        lengths = [s.length for s in self.strokes]
        self.lengths = lengths
        self.cumulative = [0.0]
        for length in lengths:
            self.cumulative.append(self.cumulative[-1] + length)
        # Estimated seconds until each stroke is done: the stroke, its travel, its pen lifts.
        leading: dict[int, list] = {}
        for travel in run.travels:
            leading.setdefault(travel.next_stroke, []).append(travel)
        # motion only: the senders weigh a stroke's motion against its link time themselves, and
        # the ETA scales by the pace the plotter shows
        seconds = [estimate(Interpretation(run.protocol, [s], leading.get(i, [])), device, link=False).total
                   for i, s in enumerate(self.strokes)]
        self.time_done = [0.0]
        for value in seconds:
            self.time_done.append(self.time_done[-1] + value)
        self.time_total = estimate(run, device, link=False).total

    @property
    def drawn_total(self) -> float:
        return self.cumulative[-1]

    def strokes_done(self, acknowledged: int) -> int:
        """Number of strokes completely executed once ``acknowledged`` bytes are."""
        return bisect.bisect_right(self.ends, acknowledged)

    def drawn(self, acknowledged: int) -> float:
        """Drawn mm, counting the stroke in progress by the share of its bytes executed."""
        done = self.strokes_done(acknowledged)
        length = self.cumulative[done]
        if done < len(self.strokes) and self.starts[done] < acknowledged:
            share = (acknowledged - self.starts[done]) / max(self.ends[done] - self.starts[done], 1)
            length += self.lengths[done] * share
        return length

    def eta(self, acknowledged: int, busy: float) -> float:
        """Seconds left; ``busy`` is the time spent so far not waiting for the operator."""
        done = self.time_done[self.strokes_done(acknowledged)]
        remaining = max(self.time_total - done, 0.0)
        if done >= 0.1 * self.time_total and done > 0:
            remaining *= min(max(busy / done, 0.2), 5.0)
        return remaining

    def event(self, kind: str, acknowledged: int, sent: int, elapsed: float,
              waited: float = 0.0, message: str = "") -> ProgressEvent:
        """The event for a job that has ``acknowledged`` bytes executed after ``elapsed`` s,
        ``waited`` of them spent waiting for the operator."""
        section = self.program.section_at(max(acknowledged - 1, 0))
        return ProgressEvent(
            kind=kind, acknowledged=acknowledged, sent=sent, total=len(self.program.text),
            drawn=self.drawn(acknowledged), drawn_total=self.drawn_total,
            strokes_done=self.strokes_done(acknowledged), strokes_total=len(self.strokes),
            layer=section.name if section is not None else "setup", elapsed=elapsed,
            eta=0.0 if kind == "done" else self.eta(acknowledged, elapsed - waited),
            message=message,
        )


def plot_summary(start: ProgressEvent | None, done: ProgressEvent, waited: float) -> dict:
    """What a finished plot did, from its first and last events: seconds taken (``waited`` of
    them for the operator) against the estimate, mm drawn and pen lifts (one per stroke), of
    this run only (a resume counts what it sent)."""
    begin = start if start is not None else done
    return {"time_s": round(done.elapsed, 1), "waited_s": round(waited, 1),
            "estimated_time_s": round(begin.eta, 1), "drawn_mm": round(done.drawn - begin.drawn, 1),
            "pen_lifts": done.strokes_done - begin.strokes_done}


def clock(seconds: float) -> str:
    """``m:ss`` or ``h:mm:ss``."""
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


def describe(event: ProgressEvent) -> str:
    """One line of text for an event."""
    head = (f"{100 * event.fraction:5.1f}%  {event.drawn:8.1f} / {event.drawn_total:.1f} mm  "
            f"{event.layer:<9} {clock(event.elapsed)} elapsed")
    if event.kind == "done":
        return f"{head}  done"
    if event.kind in ("pause", "stopped") or event.message:
        return f"{head}  {event.kind}" + (f": {event.message}" if event.message else "")
    return f"{head}  ETA {clock(event.eta)}"


class _Reporter:
    """Shared throttling: progress events at most every ``interval`` s, state changes always."""

    def __init__(self, out: TextIO, interval: float):
        self.out, self.interval = out, interval
        self.last = -1e9

    def __call__(self, event: ProgressEvent) -> None:
        now = time.monotonic()
        if event.kind == "progress" and now - self.last < self.interval:
            return
        self.last = now
        self.out.write(self.render(event))
        self.out.flush()

    def render(self, event: ProgressEvent) -> str:
        raise NotImplementedError


class ProgressBar(_Reporter):
    """A bar redrawn in place on a terminal (at most ``rate`` times a second)."""

    def __init__(self, out: TextIO, width: int = 30, rate: float = 10.0):
        super().__init__(out, 1.0 / rate)
        self.width = width

    def render(self, event: ProgressEvent) -> str:
        filled = int(round(self.width * event.fraction))
        bar = "#" * filled + "-" * (self.width - filled)
        end = "\n" if event.kind in ("pause", "done", "stopped") or event.message else ""
        return f"\r\x1b[K[{bar}] {describe(event)}{end}"


class LineReporter(_Reporter):
    """Plain lines for logs and pipes: every ``interval`` seconds and at every state change."""

    def __init__(self, out: TextIO, interval: float = 5.0):
        super().__init__(out, interval)

    def render(self, event: ProgressEvent) -> str:
        return describe(event) + "\n"


class JsonReporter(_Reporter):
    """One JSON object per event and line (``foldfab plot --json``)."""

    def __init__(self, out: TextIO, interval: float = 0.5):
        super().__init__(out, interval)

    def render(self, event: ProgressEvent) -> str:
        data = event.as_dict()
        return json.dumps({"event": data.pop("kind"), **data}) + "\n"


def reporter(out: TextIO, as_json: bool = False) -> Callable[[ProgressEvent], None]:
    """The reporter for ``out``: JSON lines, a bar on a terminal, else plain lines."""
    if as_json:
        return JsonReporter(out)
    return ProgressBar(out) if out.isatty() else LineReporter(out)
