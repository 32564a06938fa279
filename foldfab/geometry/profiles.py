"""Profile generators: sine waves, circular arcs, splines through points, and smoothing.

Smooth profiles are what the paper's vases use.  Every generator returns points whose heights
rise strictly (so no two points repeat and the paper never folds back on itself), clamped into
the trajectory's feasible region (:meth:`foldfab.geometry.feasible.Feasible.clamp`) so that
the design they make is valid, whatever the amplitude.
"""

from __future__ import annotations

import numpy as np

from foldfab.errors import DesignError
from foldfab.geometry.feasible import Feasible

KINDS = ("sine", "arc", "spline", "smooth")
MAX_POINTS = 2000
MIN_SEGMENT = 0.01
"""mm: a clamped point's line element keeps every segment at least this long, so that no face
collapses where two neighbouring points both sit on the limit."""


def sine(amplitude: float, period: float, count: int, height: float) -> np.ndarray:
    """u = amplitude · sin(2πv / period) at ``count`` heights from 0 to ``height``."""
    v = np.linspace(0.0, height, count)
    return np.column_stack([amplitude * np.sin(2 * np.pi * v / period), v])


def arc(amplitude: float, period: float, count: int, height: float) -> np.ndarray:
    """Circular arcs, one per ``period`` of height, each bulging ``amplitude`` out (in, if negative;
    at most half the period: a half circle) from u = 0 at its ends: scallops, or one bulge (a vase)
    when the period is the height."""
    v = np.linspace(0.0, height, count)
    half = period / 2
    sagitta = min(abs(amplitude), half)   # at most a half circle: a deeper arc would hang over itself
    local = np.mod(v, period)
    local[np.isclose(v, height) & np.isclose(local, 0.0) & (v > 0)] = period   # the top closes its arc
    if sagitta < 1e-12:
        return np.column_stack([np.zeros_like(v), v])
    radius = (half ** 2 + sagitta ** 2) / (2 * sagitta)
    u = sagitta - radius + np.sqrt(np.maximum(radius ** 2 - (local - half) ** 2, 0.0))
    return np.column_stack([np.sign(amplitude) * u, v])


def spline(points: np.ndarray, count: int) -> np.ndarray:
    """A Catmull-Rom spline (centripetal) through ``points`` in order, ``count`` points evenly spaced
    in its parameter, passing through the first and last point."""
    p = np.asarray(points, dtype=float)
    if len(p) < 2:
        raise DesignError("profile: a spline needs at least 2 points")
    ext = np.vstack([2 * p[0] - p[1], p, 2 * p[-1] - p[-2]])
    knots = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(ext, axis=0), axis=1) ** 0.5)])
    knots = np.maximum.accumulate(knots + 1e-12 * np.arange(len(knots)))
    out = []
    for s in np.linspace(knots[1], knots[-2], count):
        i = int(np.clip(np.searchsorted(knots, s, side="right") - 1, 1, len(p) - 1))
        t0, t1, t2, t3 = knots[i - 1:i + 3]
        p0, p1, p2, p3 = ext[i - 1:i + 3]
        a1 = (t1 - s) / (t1 - t0) * p0 + (s - t0) / (t1 - t0) * p1
        a2 = (t2 - s) / (t2 - t1) * p1 + (s - t1) / (t2 - t1) * p2
        a3 = (t3 - s) / (t3 - t2) * p2 + (s - t2) / (t3 - t2) * p3
        b1 = (t2 - s) / (t2 - t0) * a1 + (s - t0) / (t2 - t0) * a2
        b2 = (t3 - s) / (t3 - t1) * a2 + (s - t1) / (t3 - t1) * a3
        out.append((t2 - s) / (t2 - t1) * b1 + (s - t1) / (t2 - t1) * b2)
    return np.array(out)


def smooth(points: np.ndarray, passes: int) -> np.ndarray:
    """``passes`` rounds of moving each inner point halfway to the mean of its neighbours (ends kept)."""
    p = np.array(points, dtype=float)
    for _ in range(passes):
        p[1:-1] = 0.5 * p[1:-1] + 0.25 * (p[:-2] + p[2:])
    return p


def generate(kind: str, region: Feasible, offset: np.ndarray, current: np.ndarray, amplitude: float = 5.0,
             period: float = 20.0, count: int = 41, height: float | None = None, passes: int = 3,
             glue_tab: float = 0.0) -> np.ndarray:
    """A new profile of ``kind`` (:data:`KINDS`) for a design whose trajectory has ``region`` and whose
    profile is shifted by ``offset``: sine and arc from their amplitude, period, point count and height
    (default: the ``current`` profile's), spline through the current points, or the current points
    smoothed.  Clamped into the region, the first segment of every line element at least ``glue_tab``
    long (the tab lies on it); points that rise by no height are dropped."""
    current = np.asarray(current, dtype=float).reshape(-1, 2)
    if kind not in KINDS:
        raise DesignError(f"profile generator: unknown kind {kind!r}; expected one of {', '.join(KINDS)}")
    if not 2 <= count <= MAX_POINTS:
        raise DesignError(f"profile generator: points must be from 2 to {MAX_POINTS}, got {count}")
    if height is None:
        height = float(np.ptp(current[:, 1])) if len(current) else 0.0
        height = height if height > 0 else 40.0
    values = {"amplitude": amplitude, "period": period, "height": height}
    for name, value in values.items():
        if not np.isfinite(value) or abs(value) > 1e5 or (name != "amplitude" and value <= 0):
            raise DesignError(f"profile generator: {name} must be a {'number' if name == 'amplitude' else 'positive number'} "
                              f"of at most 100000 mm, got {value:g}")
    if kind == "sine":
        points = sine(amplitude, period, count, height)
    elif kind == "arc":
        points = arc(amplitude, period, count, height)
    elif kind == "spline":
        points = spline(current, count)
    else:
        points = smooth(current, int(np.clip(passes, 1, 1000)))
    if kind in ("sine", "arc") and len(current):
        points = points + [0.0, current[:, 1].min()]   # start where the current profile starts
    margin = np.full(len(region.c0), MIN_SEGMENT)
    margin[0] = max(MIN_SEGMENT, glue_tab)
    try:
        points = region.clamp(points + offset, margin) - offset
    except DesignError:
        if glue_tab <= MIN_SEGMENT:
            raise
        region.clamp(points + offset, MIN_SEGMENT)   # room without the tab: the tab is what does not fit
        raise DesignError(f"[crease].glue_tab: {glue_tab:g} mm is longer than the first segment of the line "
                          "elements can be anywhere on this trajectory; reduce glue_tab") from None
    rise = np.concatenate([[True], np.diff(points[:, 1]) > 1e-6 * max(1.0, height)])
    points = points[rise] if kind in ("sine", "arc") else points[_distinct(points)]
    if len(points) < 2:
        raise DesignError("profile generator: fewer than 2 distinct points; use more points or a larger height")
    return points


def _distinct(points: np.ndarray) -> np.ndarray:
    """A mask keeping each point that differs from the last kept one."""
    keep = np.ones(len(points), bool)
    last = points[0]
    scale = 1e-9 * max(1.0, float(np.abs(points).max()))
    for i in range(1, len(points)):
        keep[i] = np.linalg.norm(points[i] - last) > scale
        if keep[i]:
            last = points[i]
    return keep
