"""Timed execution: the interpreters' machines, with every move and pen lift as a Block.

A simulator runs :class:`~foldfab.interpret.HPGLMachine` or
:class:`~foldfab.interpret.GcodeMachine` with the :class:`Timed` mixin: each pen move,
pen down and pen up the machine makes is handed to the simulator as a :class:`Block`
with its duration, which the simulator executes on its virtual clock.

Durations follow :mod:`foldfab.estimate` exactly, so a simulated run's busy time equals
the estimate of the same program: a pen-up move is one trapezoid at the travel speed; a
pen-down move that continues the previous one within ``CONTINUATION_ANGLE`` extends
that straight run (it costs ``T(run + l) - T(run)``, so the run costs ``T(run)`` in
all, as the estimate counts it) and any other starts a new run; each pen down and pen
up costs ``pen_lift_time``.  A block also carries a recording mark, so a simulator can
tell which strokes are drawn once the block has started.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Callable

from foldfab.estimate import CONTINUATION_ANGLE, move_times
from foldfab.interpret import GcodeMachine, HPGLMachine, Stroke

Point = tuple[float, float]


@dataclass
class Block:
    """One timed step of the machine: a move, a pen lift or a dwell."""

    duration: float
    start: Point
    end: Point
    """Device units, for position reports."""
    feed: float
    """mm/s while moving (0 for lifts and dwells)."""
    mark: tuple[int, int]
    """Recording mark after this block: (finished strokes, points of the open stroke)."""
    done: Callable[[], None] | None = None
    """Called when the block has been executed (e.g. to send GRBL's deferred ``ok``)."""
    z: float = 0.0
    """G-code: the Z height during the block (for status reports)."""


class Timed:
    """Mixin for a machine: report each move and pen lift to ``sink`` as a Block."""

    sink: Callable[[Block], None]

    def start_timing(self, sink: Callable[[Block], None]) -> None:
        self.sink = sink
        self._run = 0.0  # length of the straight pen-down run so far (mm)
        self._heading: Point | None = None

    def lift_duration(self) -> float:
        """Seconds for one pen down or pen up."""
        return self.device.motion.pen_lift_time

    def lower(self, offset: int, **meta) -> None:
        was_up = self.stroke is None
        super().lower(offset, **meta)
        if was_up:
            self._heading = None
            self._emit(self.lift_duration(), self.position, 0.0)

    def lift(self) -> None:
        was_down = self.stroke is not None
        super().lift()
        if was_down:
            self._emit(self.lift_duration(), self.position, 0.0)

    def move_to(self, target: Point) -> None:
        start, down = self.position, self.stroke is not None
        super().move_to(target)
        if not down and target == start:
            return
        motion = self.device.motion
        dx, dy = ((b - a) / self.device.units_per_mm for a, b in zip(start, target))
        length = math.hypot(dx, dy)
        if not down:
            self._heading = None
            speed = motion.travel_speed
            self._emit(float(move_times(length, speed, motion.acceleration)), start, speed)
            return
        speed = self.stroke_meta["speed"]
        duration = 0.0
        if length > 0:
            before = 0.0
            if self._heading is not None and abs(math.atan2(
                    self._heading[0] * dy - self._heading[1] * dx,
                    self._heading[0] * dx + self._heading[1] * dy)) <= CONTINUATION_ANGLE:
                before = self._run
            self._run = before + length
            times = move_times([before, self._run], speed, motion.acceleration)
            duration = float(times[1] - times[0])  # T(0) = 0
            self._heading = (dx, dy)
        self._emit(duration, start, speed)

    def _emit(self, duration: float, start: Point, feed: float) -> None:
        self.sink(Block(duration, start, self.position, feed, self.mark()))

    def mark(self) -> tuple[int, int]:
        """The recording state now: (finished strokes, points of the open stroke)."""
        return len(self.result.strokes), len(self.stroke) if self.stroke is not None else 0

    def strokes_at(self, mark: tuple[int, int]) -> list[Stroke]:
        """The strokes as they were at ``mark`` (an open stroke cut to its points then)."""
        finished, points = mark
        strokes = list(self.result.strokes[:finished])
        if points:
            if finished < len(self.result.strokes):
                stroke = self.result.strokes[finished]
            else:
                stroke = self.open_stroke()
            strokes.append(dataclasses.replace(stroke, points=stroke.points[:points]))
        return strokes


class TimedHPGL(Timed, HPGLMachine):
    """HP-GL machine with timed blocks."""


class TimedGcode(Timed, GcodeMachine):
    """G-code machine with timed blocks; a servo pen moves during the program's ``G4`` dwell."""

    def lift_duration(self) -> float:
        return 0.0 if self.servo else self.device.motion.pen_lift_time
