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


def move_times(lengths: np.ndarray, speed: float | np.ndarray, acceleration: float) -> np.ndarray:
    """Seconds for straight moves of ``lengths`` (mm), each from rest to rest (trapezoid).

    ``speed`` is one for all moves or one per move.
    """
    import numpy as np

    lengths = np.asarray(lengths, dtype=float)
    ramp = speed * speed / acceleration  # distance to reach full speed and stop again
    return np.where(lengths >= ramp, lengths / speed + speed / acceleration,
                    2.0 * np.sqrt(lengths / acceleration))


def straight_runs(points: np.ndarray) -> np.ndarray:
    """Lengths of the straight moves in a polyline: collinear segments merged, zero ones dropped."""
    import numpy as np

    return polyline_runs(points, np.zeros(1, dtype=np.intp))[1]


def polyline_runs(points: np.ndarray, starts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Polylines stored one after another in ``points`` (N, 2), polyline k from row ``starts[k]``.

    Returns each polyline's length, the lengths of all their straight moves in order (as
    :func:`straight_runs` finds them in each polyline) and the polyline of each move.
    """
    import numpy as np

    count = len(starts)
    owner = np.repeat(np.arange(count), np.diff(starts, append=len(points)))  # polyline of each point
    steps = np.diff(points, axis=0)
    lengths = np.hypot(steps[:, 0], steps[:, 1])
    within = owner[1:] == owner[:-1]  # the segment joins two points of one polyline
    steps, lengths, owner = steps[within], lengths[within], owner[1:][within]
    totals = np.bincount(owner, weights=lengths, minlength=count)
    moving = lengths > 0
    steps, lengths, owner = steps[moving], lengths[moving], owner[moving]
    if not len(lengths):
        return totals, lengths, owner
    cross = steps[:-1, 0] * steps[1:, 1] - steps[:-1, 1] * steps[1:, 0]
    dot = (steps[:-1] * steps[1:]).sum(axis=1)
    corner = (np.abs(np.arctan2(cross, dot)) > CONTINUATION_ANGLE) | (owner[1:] != owner[:-1])
    runs = np.concatenate([[0], np.flatnonzero(corner) + 1])
    return totals, np.add.reduceat(lengths, runs), owner[runs]


def estimate(interpretation: Interpretation, device: DeviceProfile) -> Estimate:
    """Estimate the run time of ``interpretation`` on ``device``."""
    import numpy as np

    motion = device.motion
    strokes, travels = interpretation.strokes, interpretation.travels
    names: dict[str, int] = {}  # layer name -> index, in order of first appearance
    stroke_layers = np.array([names.setdefault(s.layer, len(names)) for s in strokes], dtype=np.intp)
    speeds = np.array([s.speed for s in strokes], dtype=float)
    sizes = np.array([len(s.points) for s in strokes], dtype=np.intp)
    points = np.concatenate([s.points for s in strokes]) if strokes else np.zeros((0, 2))
    lengths, runs, owners = polyline_runs(points, np.cumsum(sizes) - sizes)
    run_times = move_times(runs, speeds[owners], motion.acceleration)
    seconds = np.bincount(owners, weights=run_times, minlength=len(strokes))
    ends = np.array([(*t.start, *t.end) for t in travels], dtype=float).reshape(-1, 4)
    travel_lengths = np.hypot(ends[:, 2] - ends[:, 0], ends[:, 3] - ends[:, 1])
    travel_times = move_times(travel_lengths, motion.travel_speed, motion.acceleration)
    if strokes:
        leads_to = np.array([t.next_stroke for t in travels], dtype=np.intp)
        travel_layers = stroke_layers[np.minimum(leads_to, len(strokes) - 1)]
    else:
        if travels:
            names["travel"] = 0
        travel_layers = np.zeros(len(travels), dtype=np.intp)
    count = len(names)
    lifts = np.bincount(stroke_layers, minlength=count)
    drawn = np.bincount(stroke_layers, weights=lengths, minlength=count)
    travelled = np.bincount(travel_layers, weights=travel_lengths, minlength=count)
    # each layer's strokes, then the travels that lead to it, each in order (bincount adds in order)
    times = np.bincount(np.concatenate([stroke_layers, travel_layers]),
                        weights=np.concatenate([seconds + 2 * motion.pen_lift_time, travel_times]),
                        minlength=count)
    layers = {name: LayerTime(float(drawn[i]), int(lifts[i]), float(travelled[i]), float(times[i]))
              for name, i in names.items()}
    lift_time = 2 * motion.pen_lift_time * len(strokes)
    lower = _running_total(lengths / speeds)
    return Estimate(_running_total(seconds), float(travel_times.sum()), lift_time,
                    lower + lift_time, layers)


def _running_total(values: np.ndarray) -> float:
    """The sum of ``values`` added one by one in order (as a loop over strokes adds them)."""
    import numpy as np

    return float(np.cumsum(values)[-1]) if len(values) else 0.0
