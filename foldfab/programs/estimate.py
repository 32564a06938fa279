"""Plot-time estimate from an interpreted program.

Two motion models, chosen by the device profile:

* Stop at corners (profiles without ``junction_deviation``, such as the HP-GL plotters).  Every
  straight move accelerates from rest at the profile's ``acceleration``, cruises at its
  speed (the stroke's speed when drawing) if it is long enough, and decelerates to rest.
  Consecutive drawn segments that turn by less than ``CONTINUATION_ANGLE`` count as one
  move (a straight line split into many points is not slowed down at every point); any
  sharper corner is taken from rest.
* Junction speeds (a ``junction_deviation``: GRBL's ``$11``).  Each stroke is planned as
  GRBL 1.1 plans it (``planner.c``) with unlimited look-ahead: it starts and ends at rest,
  each vertex may be passed at the junction speed :func:`junction_limits` allows, and
  :func:`plan_speeds` gives every vertex the highest speed that acceleration allows on
  the way there and to every later stop; each segment is then a trapezoid (or triangle)
  from its entry to its exit speed (:func:`segment_times`).  GRBL's planner looks only
  as far ahead as its buffer holds, so a real (or simulated) run may take a little longer.

In both, a pen-up move is one rest-to-rest trapezoid at the profile's ``travel_speed``,
each pen down and each pen up costs the profile's ``pen_lift_time``, and pauses for the
operator are not counted.  A profile with ``axis_limits`` (GRBL's: its ``$110``/``$111``
and ``$120``/``$121`` are per axis) gives each move the travel speed and acceleration
times its :func:`axis_factors`, and caps a drawing speed at the travel speed so scaled,
as GRBL's planner does; a junction's acceleration is scaled along the difference of the
two moves' directions.  Otherwise the one ``acceleration`` serves every direction.

The link: the plotter cannot finish a stroke before the program's bytes up to its end have
come down the line (start, data, parity and stop bits per byte at the profile's ``[serial]``
baud rate, counted from the program's first byte), so on a slow line the link, not motion,
sets the pace; :func:`link_waits` adds what each stroke waits for its bytes beyond its own
motion, as if the plotter's buffer were as large as it needs (``link_wait``).

``lower_bound`` is what no plan can beat for the same strokes: drawn length at the
draw speed with infinite acceleration, plus one pen down and one pen up per stroke.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np

    from foldfab.devices import DeviceProfile, Motion
    from foldfab.programs.drawing import Drawn
    from foldfab.programs.machine import Interpretation

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
    link_wait: float = 0.0
    """Seconds the plotter waits for the link beyond its motion (see :func:`link_waits`)."""

    @property
    def total(self) -> float:
        return self.draw_time + self.travel_time + self.lift_time + self.link_wait


def link_waits(byte_ends: np.ndarray, motion_seconds: np.ndarray, device: DeviceProfile) -> np.ndarray:
    """Seconds each stroke waits for its bytes beyond its motion (``motion_seconds``: its draw,
    lift and travel time; ``byte_ends``: where in the program each stroke's bytes end).  Stroke k
    ends at ``T[k] = max(T[k-1] + m[k], L[k])`` (``L``: when its last byte has arrived, the
    program sent from its first byte), that is ``T = M + max(0, max over j <= k of L[j] - M[j])``
    with ``M`` the running motion total."""
    import numpy as np

    if not len(byte_ends):
        return np.zeros(0)
    line = device.serial
    byte_time = (1 + line.bytesize + (line.parity != "N") + line.stopbits) / line.baudrate
    motion = np.cumsum(motion_seconds)
    done = motion + np.maximum.accumulate(np.maximum(np.asarray(byte_ends, dtype=float) * byte_time - motion, 0.0))
    return np.maximum(np.diff(done, prepend=0.0) - motion_seconds, 0.0)


def axis_factors(steps: np.ndarray) -> np.ndarray:
    """How far beyond its per-axis limits a move along ``steps`` (..., 2; mm) may go, on a
    machine whose axes have the same speed and acceleration limits: its length over its
    larger component (1 along an axis, 1.41 at 45 degrees; 1 for a zero step).  GRBL's
    ``limit_value_by_axis_maximum`` (``planner.c``) for equal settings on both axes."""
    import numpy as np

    steps = np.asarray(steps, dtype=float)
    larger = np.abs(steps).max(axis=-1)
    return np.hypot(steps[..., 0], steps[..., 1]) / np.where(larger > 0, larger, 1.0) + (larger == 0)


def move_limits(steps: np.ndarray, speeds: float | np.ndarray, motion: Motion) -> tuple:
    """Speed and acceleration of drawn moves along ``steps`` (..., 2) at ``speeds``: as given and
    the profile's, or with ``axis_limits`` the acceleration times each move's factor and the
    speed at most the travel speed times it (GRBL caps a feed at the rapid rate)."""
    import numpy as np

    if not motion.axis_limits:
        return speeds, motion.acceleration
    factors = axis_factors(steps)
    return np.minimum(speeds, motion.travel_speed * factors), motion.acceleration * factors


def travel_times(steps: np.ndarray, motion: Motion) -> np.ndarray:
    """Seconds for pen-up moves along ``steps`` (..., 2; mm), each from rest to rest at the
    profile's travel speed and acceleration (times each move's factor with ``axis_limits``)."""
    import numpy as np

    steps = np.asarray(steps, dtype=float)
    factors = axis_factors(steps) if motion.axis_limits else 1.0
    return move_times(np.hypot(steps[..., 0], steps[..., 1]), motion.travel_speed * factors,
                      motion.acceleration * factors)


def move_times(lengths: np.ndarray, speed: float | np.ndarray,
               acceleration: float | np.ndarray) -> np.ndarray:
    """Seconds for straight moves of ``lengths`` (mm), each from rest to rest (trapezoid).

    ``speed`` and ``acceleration`` are one for all moves or one per move.
    """
    import numpy as np

    lengths = np.asarray(lengths, dtype=float)
    ramp = speed * speed / acceleration  # distance to reach full speed and stop again
    return np.where(lengths >= ramp, lengths / speed + speed / acceleration,
                    2.0 * np.sqrt(lengths / acceleration))


def junction_limits(before: np.ndarray, after: np.ndarray, speeds: float | np.ndarray,
                    acceleration: float | np.ndarray, deviation: float) -> np.ndarray:
    """Squared speeds (mm²/s²) GRBL 1.1 allows through junctions between moves along the unit
    vectors ``before`` and ``after`` (shape (..., 2)), both at nominal ``speeds`` (mm/s).

    As ``planner.c``: a reversal stops, a straight junction is not limited, any other
    passes at ``v² = acceleration deviation s / (1 - s)``, ``s = sin(θ/2)`` with
    ``cos θ = -before·after``; at most the nominal speed squared.
    """
    import numpy as np

    cos_theta = -(np.asarray(before, dtype=float) * after).sum(axis=-1)
    sin_half = np.sqrt(0.5 * (1.0 - np.clip(cos_theta, -0.999999, 0.999999)))
    limit = np.where(cos_theta > 0.999999, 0.0, acceleration * deviation * sin_half / (1.0 - sin_half))
    return np.minimum(np.where(cos_theta < -0.999999, np.inf, limit), np.square(speeds))


def junction_speeds(before: np.ndarray, after: np.ndarray, speed_before: float | np.ndarray,
                    speed_after: float | np.ndarray, motion: Motion) -> np.ndarray:
    """Squared speeds a profile allows through junctions between moves along the unit vectors
    ``before`` and ``after`` at their nominal speeds: :func:`junction_limits` at the slower of
    the two, with the acceleration taken along ``after - before`` (per axis with
    ``axis_limits``), as GRBL's planner takes it."""
    import numpy as np

    _, acceleration = move_limits(np.subtract(after, before), 0.0, motion)
    return junction_limits(before, after, np.minimum(speed_before, speed_after), acceleration,
                           motion.junction_deviation)


def plan_speeds(limits: np.ndarray, lengths: np.ndarray, acceleration: float | np.ndarray) -> np.ndarray:
    """Squared speeds at the n + 1 ends of n consecutive moves of ``lengths`` (mm): each as high
    as its ``limit`` allows while acceleration can reach it from the ends before and still
    slow down to the limits of the ends after (GRBL's backward and forward passes).

    The passes ``w[i] = min(J[i], w[i+1] + 2aL[i])`` and ``u[i] = min(w[i], u[i-1] + 2aL[i-1])``
    unroll to ``w[i] = min(J[k] + 2aS[k], k >= i) - 2aS[i]`` and ``u[i] = min(w[k] - 2aS[k],
    k <= i) + 2aS[i]`` (``S``: distance from the first end): one ``np.minimum.accumulate``
    each, backwards then forwards (``2aS``: the sum of ``2aL`` over the moves before, so
    ``acceleration`` may be one per move).  A zero limit makes the moves on either side
    independent.
    """
    import numpy as np

    reach = np.concatenate([[0.0], np.cumsum(2.0 * np.multiply(acceleration, lengths))])
    backward = np.minimum.accumulate((np.asarray(limits, dtype=float) + reach)[::-1])[::-1] - reach
    return np.minimum.accumulate(backward - reach) + reach


def segment_times(lengths: np.ndarray, speeds: float | np.ndarray, entry: np.ndarray,
                  leave: np.ndarray, acceleration: float | np.ndarray) -> np.ndarray:
    """Seconds for moves of ``lengths`` (mm) entered and left at squared speeds ``entry`` and
    ``leave`` (each reachable from the other), cruising at ``speeds`` if the move is long
    enough (trapezoid), else turning at the highest speed it reaches (triangle)."""
    import numpy as np

    lengths, entry, leave = (np.asarray(x, dtype=float) for x in (lengths, entry, leave))
    mean = 0.5 * (entry + leave)
    peak = np.minimum(np.square(speeds), mean + acceleration * lengths)  # squared
    cruise = np.maximum(lengths - (peak - mean) / acceleration, 0.0)
    return (2.0 * np.sqrt(peak) - np.sqrt(entry) - np.sqrt(leave)) / acceleration + cruise / speeds


def straight_runs(points: np.ndarray) -> np.ndarray:
    """Lengths of the straight moves in a polyline: collinear segments merged, zero ones dropped."""
    import numpy as np

    return polyline_runs(points, np.zeros(1, dtype=np.intp))[1]


def _segments(points: np.ndarray, starts: np.ndarray) -> tuple[np.ndarray, ...]:
    """Each polyline's length, then the steps, lengths and polyline of its non-zero segments."""
    import numpy as np

    count = len(starts)
    owner = np.repeat(np.arange(count), np.diff(starts, append=len(points)))  # polyline of each point
    steps = np.diff(points, axis=0)
    lengths = np.hypot(steps[:, 0], steps[:, 1])
    within = owner[1:] == owner[:-1]  # the segment joins two points of one polyline
    steps, lengths, owner = steps[within], lengths[within], owner[1:][within]
    totals = np.bincount(owner, weights=lengths, minlength=count)
    moving = lengths > 0
    return totals, steps[moving], lengths[moving], owner[moving]


def polyline_runs(points: np.ndarray, starts: np.ndarray) -> tuple[np.ndarray, ...]:
    """Polylines stored one after another in ``points`` (N, 2), polyline k from row ``starts[k]``.

    Returns each polyline's length, the lengths of all their straight moves in order (as
    :func:`straight_runs` finds them in each polyline), the polyline of each move and the
    step of each move's first segment (its direction).
    """
    import numpy as np

    totals, steps, lengths, owner = _segments(points, starts)
    if not len(lengths):
        return totals, lengths, owner, steps
    cross = steps[:-1, 0] * steps[1:, 1] - steps[:-1, 1] * steps[1:, 0]
    dot = (steps[:-1] * steps[1:]).sum(axis=1)
    corner = (np.abs(np.arctan2(cross, dot)) > CONTINUATION_ANGLE) | (owner[1:] != owner[:-1])
    runs = np.concatenate([[0], np.flatnonzero(corner) + 1])
    return totals, np.add.reduceat(lengths, runs), owner[runs], steps[runs]


def planned_segments(points: np.ndarray, starts: np.ndarray, speeds: np.ndarray,
                     motion: Motion) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Polylines stored as for :func:`polyline_runs`, polyline k drawn at ``speeds[k]``, each
    planned from rest to rest with junction speeds (the profile's ``junction_deviation``).

    Returns each polyline's length, the seconds of all their non-zero segments in order and
    the polyline of each segment.
    """
    import numpy as np

    totals, steps, lengths, owner = _segments(points, starts)
    units = steps / lengths[:, None]
    speed, acceleration = move_limits(steps, speeds[owner], motion)
    speed = np.broadcast_to(speed, lengths.shape)
    limits = np.zeros(len(lengths) + 1)  # at each end of each segment; polylines end at rest
    limits[1:-1] = np.where(owner[1:] == owner[:-1],
                            junction_speeds(units[:-1], units[1:], speed[:-1], speed[1:], motion), 0.0)
    ends = plan_speeds(limits, lengths, acceleration)
    return totals, segment_times(lengths, speed, ends[:-1], ends[1:], acceleration), owner


def estimate(interpretation: Interpretation, device: DeviceProfile, link: bool = True) -> Estimate:
    """Estimate the run time of ``interpretation`` on ``device`` (``link``: with the waits for
    the serial line, :func:`link_waits`; without, motion only)."""
    from foldfab.programs.machine import from_interpretation

    return estimate_drawn(from_interpretation(interpretation), device, link)


def estimate_drawn(drawn: Drawn, device: DeviceProfile, link: bool = True) -> Estimate:
    """Estimate the run time on ``device`` of what a program draws (:class:`~foldfab.programs.drawing.Drawn`:
    read back, or recorded by the writer; ``link`` as :func:`estimate`)."""
    import numpy as np

    motion = device.motion
    names = dict(zip(drawn.names, range(len(drawn.names))))  # layer name -> index, in order of first appearance
    stroke_layers, speeds, points, starts = drawn.layers, drawn.speeds, drawn.points, drawn.starts
    strokes = len(starts)
    if motion.junction_deviation is None:
        lengths, runs, owners, heads = polyline_runs(points, starts)
        run_times = move_times(runs, *move_limits(heads, speeds[owners], motion))
    else:
        lengths, run_times, owners = planned_segments(points, starts, speeds, motion)
    seconds = np.bincount(owners, weights=run_times, minlength=strokes)
    ends = drawn.travels
    steps = ends[:, 2:] - ends[:, :2]
    travel_lengths = np.hypot(steps[:, 0], steps[:, 1])
    moves = travel_times(steps, motion)
    waits = np.zeros(strokes)
    if strokes:
        leads_to = np.minimum(drawn.leads_to, strokes - 1)
        travel_layers = stroke_layers[leads_to]
        if link and drawn.byte_ends is not None:
            waits = link_waits(drawn.byte_ends, seconds + 2 * motion.pen_lift_time
                               + np.bincount(leads_to, weights=moves, minlength=strokes), device)
    else:
        if len(ends):
            names["travel"] = 0
        travel_layers = np.zeros(len(ends), dtype=np.intp)
    count = len(names)
    lifts = np.bincount(stroke_layers, minlength=count)
    drawn_lengths = np.bincount(stroke_layers, weights=lengths, minlength=count)
    travelled = np.bincount(travel_layers, weights=travel_lengths, minlength=count)
    # each layer's strokes, then the travels that lead to it, each in order (bincount adds in order)
    times = np.bincount(np.concatenate([stroke_layers, travel_layers]),
                        weights=np.concatenate([seconds + 2 * motion.pen_lift_time + waits, moves]),
                        minlength=count)
    layers = {name: LayerTime(float(drawn_lengths[i]), int(lifts[i]), float(travelled[i]), float(times[i]))
              for name, i in names.items()}
    lift_time = 2 * motion.pen_lift_time * strokes
    lower = _running_total(lengths / speeds)
    return Estimate(_running_total(seconds), float(moves.sum()), lift_time,
                    lower + lift_time, layers, _running_total(waits))


def _running_total(values: np.ndarray) -> float:
    """The sum of ``values`` added one by one in order (as a loop over strokes adds them)."""
    import numpy as np

    return float(np.cumsum(values)[-1]) if len(values) else 0.0
