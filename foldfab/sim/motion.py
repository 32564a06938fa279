"""Timed execution: the interpreters' machines, with every move and pen lift as a Block.

A simulator runs :class:`~foldfab.programs.read_hpgl.HPGLMachine` or
:class:`~foldfab.programs.read_gcode.GcodeMachine` with the :class:`Timed` mixin: each pen move,
pen down and pen up the machine makes is handed to the simulator as a :class:`Block`,
which the simulator executes on its virtual clock.

Durations follow :mod:`foldfab.programs.estimate`'s model for the device.  A pen-up move is one
trapezoid at the travel speed; each pen down and pen up costs ``pen_lift_time``; with
``axis_limits`` every move's speed and acceleration are scaled by its axis factor as the
estimate scales them.

* Stop at corners (no ``junction_deviation``): every block has its duration when it is
  made, and a simulated run's busy time equals the estimate of the same program.  A
  pen-down move that continues the previous one within ``CONTINUATION_ANGLE`` extends
  that straight run (it costs ``T(run + l) - T(run)``, so the run costs ``T(run)`` in
  all, as the estimate counts it) and any other starts a new run.
* Junction speeds (a ``junction_deviation``): a pen-down move is a *planned* block that
  carries its length, speed and the highest entry speed its junction with the move
  before allows (:func:`~foldfab.programs.estimate.junction_speeds`, as GRBL computes it when a
  block enters its planner).  Its duration is fixed when it starts
  (:func:`plan_start`): it enters at the speed the block before left at, and leaves at
  the speed a backward pass over the blocks then in the planner allows, the last of
  which must be able to stop.  Lifts, dwells and pen-up moves start and end at rest.
  With a short look-ahead a run takes a little longer than the estimate (which looks
  ahead without limit), never less.

A block also carries a recording mark, so a simulator can tell which strokes are drawn
once the block has started.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass
from typing import Callable, Sequence

from foldfab.programs.estimate import (CONTINUATION_ANGLE, junction_speeds, move_limits, move_times, plan_speeds,
                              segment_times, travel_times)
from foldfab.programs.machine import Stroke
from foldfab.programs.read_gcode import GcodeMachine
from foldfab.programs.read_gpgl import GPGLMachine
from foldfab.programs.read_hpgl import HPGLMachine

Point = tuple[float, float]


@dataclass
class Block:
    """One timed step of the machine: a move, a pen lift or a dwell."""

    duration: float | None
    """Seconds; None for a planned block until it starts."""
    start: Point
    end: Point
    """Device units, for position reports."""
    feed: float
    """mm/s while moving (0 for lifts and dwells); a planned block's nominal speed."""
    mark: tuple[int, int]
    """Recording mark after this block: (finished strokes, points of the open stroke)."""
    done: Callable[[], None] | None = None
    """Called when the block has been executed (e.g. to send GRBL's deferred ``ok``)."""
    z: float = 0.0
    """G-code: the Z height during the block (for status reports)."""
    planned: bool = False
    """A pen-down move under the junction model: its speeds at both ends depend on its
    neighbours (other blocks start and end at rest)."""
    length: float = 0.0
    """mm, of a planned block (zero-length ones take no time and do not stop the head)."""
    entry_limit: float = 0.0
    """A planned block's highest entry speed squared (mm²/s²): its junction with the move before."""
    acceleration: float = 0.0
    """A planned block's acceleration (mm/s²)."""


def plan_start(blocks: Sequence[Block], entry: float) -> tuple[float, float]:
    """Duration and squared exit speed of the first of ``blocks`` (the planner, head first, a
    planned block) when it starts at squared speed ``entry``.

    Its exit speed comes from the passes of :func:`~foldfab.programs.estimate.plan_speeds` over the
    planned blocks behind it, up to the first block that starts at rest or the end of the
    buffer, where the machine must be able to stop (as GRBL plans).
    """
    import numpy as np

    head = blocks[0]
    if not head.length:  # no time, and the speed carries on to the next move
        return 0.0, entry
    lengths, limits, accelerations = [head.length], [entry], [head.acceleration]
    for block in itertools.islice(blocks, 1, None):
        if not block.planned:
            break
        if block.length:
            limits.append(block.entry_limit)
            lengths.append(block.length)
            accelerations.append(block.acceleration)
    limits.append(0.0)
    leave = float(plan_speeds(np.array(limits), np.array(lengths), np.array(accelerations))[1])
    return float(segment_times(head.length, head.feed, entry, leave, head.acceleration)), leave


class Timed:
    """Mixin for a machine: report each move and pen lift to ``sink`` as a Block."""

    sink: Callable[[Block], None]
    on_the_fly = False
    """The tool switches while the head moves (a laser's beam): no block, no stop."""

    def start_timing(self, sink: Callable[[Block], None]) -> None:
        self.sink = sink
        self._run = 0.0  # length of the straight pen-down run so far (mm)
        self._run_limits = (0.0, 0.0)  # its speed and acceleration
        self._heading: Point | None = None  # direction of the last non-zero pen-down move
        self._nominal = 0.0  # speed of the last planned block

    def lift_duration(self) -> float:
        """Seconds for one pen down or pen up."""
        return self.device.motion.pen_lift_time

    def lower(self, offset: int, **meta) -> None:
        was_up = self.stroke is None
        super().lower(offset, **meta)
        if was_up and not self.on_the_fly:
            self._heading = None
            self._emit(self.lift_duration(), self.position, 0.0)

    def lift(self) -> None:
        was_down = self.stroke is not None
        super().lift()
        if was_down and not self.on_the_fly:
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
            self._emit(float(travel_times((dx, dy), motion)), start, motion.travel_speed)
        elif motion.junction_deviation is None:
            self._extend_run(start, dx, dy, length)
        else:
            self._plan(start, dx, dy, length)

    def _extend_run(self, start: Point, dx: float, dy: float, length: float) -> None:
        """A drawn move that stops at corners: it extends the straight run or starts a new one."""
        speed = self.stroke_meta["speed"]
        duration = 0.0
        if length > 0:
            before = 0.0
            if self._heading is not None and abs(math.atan2(
                    self._heading[0] * dy - self._heading[1] * dx,
                    self._heading[0] * dx + self._heading[1] * dy)) <= CONTINUATION_ANGLE:
                before = self._run
            else:  # a new run: its first move's direction sets its limits, as in the estimate
                self._run_limits = tuple(map(float, move_limits((dx, dy), speed, self.device.motion)))
            self._run = before + length
            times = move_times([before, self._run], *self._run_limits)
            duration = float(times[1] - times[0])  # T(0) = 0
            self._heading = (dx, dy)
        self._emit(duration, start, speed)

    def _plan(self, start: Point, dx: float, dy: float, length: float) -> None:
        """A drawn move under the junction model: a planned block, timed when it starts."""
        motion = self.device.motion
        speed, acceleration = map(float, move_limits((dx, dy), self.stroke_meta["speed"], motion))
        limit = 0.0
        if length > 0:
            direction = (dx / length, dy / length)
            if self._heading is not None:
                limit = float(junction_speeds(self._heading, direction, self._nominal, speed, motion))
            self._heading, self._nominal = direction, speed
        self.sink(Block(None, start, self.position, speed, self.mark(), planned=True,
                        length=length, entry_limit=limit, acceleration=acceleration))

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


class TimedGPGL(Timed, GPGLMachine):
    """GP-GL machine with timed blocks."""


class TimedGcode(Timed, GcodeMachine):
    """G-code machine with timed blocks; a servo pen moves during the program's ``G4`` dwell, a
    laser's beam switches on the fly (GRBL's laser mode: power changes on moves do not stop it)."""

    @property
    def on_the_fly(self) -> bool:
        return self.laser

    def lift_duration(self) -> float:
        return 0.0 if self.servo else self.device.motion.pen_lift_time
