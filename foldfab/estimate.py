"""Plot-time estimate from an interpreted program.

Motion model: every straight move accelerates from rest at the profile's
``acceleration``, cruises at its speed (the stroke's speed when drawing, the profile's
``travel_speed`` when the pen is up) if it is long enough, and decelerates to rest.
Consecutive drawn segments that turn by less than ``CONTINUATION_ANGLE`` count as one
move (a straight line split into many points is not slowed down at every point);
any sharper corner is taken from rest.  This is pessimistic for GRBL, whose
junction deviation keeps some speed through shallow corners, and about right for
plotters that stop at every vertex.  Each pen down and each pen up costs the
profile's ``pen_lift_time``; pauses for the operator are not counted.

``lower_bound`` is what no plan can beat for the same strokes: drawn length at the
draw speed with infinite acceleration, plus one pen down and one pen up per stroke.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np

    from foldfab.devices import DeviceProfile
    from foldfab.interpret import Interpretation

CONTINUATION_ANGLE = math.radians(1.0)


@dataclass
class LayerTime:
    """Totals for one layer: drawn mm, strokes (= pen lifts), pen-up travel mm, seconds."""

    drawn_length: float = 0.0
    pen_lifts: int = 0
    travel_length: float = 0.0
    time: float = 0.0


@dataclass
class Estimate:
    """Seconds to run a program, its parts, and a lower bound."""

    draw_time: float
    travel_time: float
    lift_time: float
    lower_bound: float
    layers: dict[str, LayerTime] = field(default_factory=dict)
    """Per layer name in order of first appearance; a travel counts for the layer it leads to."""

    @property
    def total(self) -> float:
        return self.draw_time + self.travel_time + self.lift_time


def move_times(lengths: np.ndarray, speed: float, acceleration: float) -> np.ndarray:
    """Seconds for straight moves of ``lengths`` (mm), each from rest to rest (trapezoid)."""
    import numpy as np

    lengths = np.asarray(lengths, dtype=float)
    ramp = speed * speed / acceleration  # distance to reach full speed and stop again
    return np.where(lengths >= ramp, lengths / speed + speed / acceleration,
                    2.0 * np.sqrt(lengths / acceleration))


def straight_runs(points: np.ndarray) -> np.ndarray:
    """Lengths of the straight moves in a polyline: collinear segments merged, zero ones dropped."""
    import numpy as np

    steps = np.diff(points, axis=0)
    lengths = np.hypot(steps[:, 0], steps[:, 1])
    steps, lengths = steps[lengths > 0], lengths[lengths > 0]
    if not len(lengths):
        return lengths
    cross = steps[:-1, 0] * steps[1:, 1] - steps[:-1, 1] * steps[1:, 0]
    dot = (steps[:-1] * steps[1:]).sum(axis=1)
    corner = np.abs(np.arctan2(cross, dot)) > CONTINUATION_ANGLE
    starts = np.concatenate([[0], np.flatnonzero(corner) + 1])
    return np.add.reduceat(lengths, starts)


def estimate(interpretation: Interpretation, device: DeviceProfile) -> Estimate:
    """Estimate the run time of ``interpretation`` on ``device``."""
    import numpy as np

    motion = device.motion
    layers: dict[str, LayerTime] = {}
    draw_time = lower = 0.0
    for stroke in interpretation.strokes:
        stats = layers.setdefault(stroke.layer, LayerTime())
        length = stroke.length
        seconds = float(move_times(straight_runs(stroke.points), stroke.speed,
                                   motion.acceleration).sum())
        stats.drawn_length += length
        stats.pen_lifts += 1
        stats.time += seconds + 2 * motion.pen_lift_time
        draw_time += seconds
        lower += length / stroke.speed
    travel_time = 0.0
    strokes = interpretation.strokes
    if interpretation.travels:
        ends = np.array([[t.start, t.end] for t in interpretation.travels])
        lengths = np.hypot(*(ends[:, 1] - ends[:, 0]).T)
        times = move_times(lengths, motion.travel_speed, motion.acceleration)
        travel_time = float(times.sum())
        for travel, length, seconds in zip(interpretation.travels, lengths, times):
            if strokes:
                stroke = strokes[min(travel.next_stroke, len(strokes) - 1)]
                stats = layers.setdefault(stroke.layer, LayerTime())
            else:
                stats = layers.setdefault("travel", LayerTime())
            stats.travel_length += float(length)
            stats.time += float(seconds)
    lift_time = 2 * motion.pen_lift_time * len(strokes)
    return Estimate(draw_time, travel_time, lift_time, lower + lift_time, layers)
