"""Where profile points may go: the region of (u, v) whose line elements meet the mirrors in order.

Segment ``k`` of the line element of a profile point (u, v) is ``c0[k] + cu[k]·u + cv[k]·v``
long (:meth:`foldfab.geometry.reflection.Planes.limits`); :func:`~foldfab.geometry.reflection.reflect`
refuses a design where one is negative, and its message names the limit.  Each point has its
own line element, so the rule is the same for every point: the points must lie in the
intersection of these half-planes, a convex region.  The studio shades it, keeps template
edits inside it (:func:`min_scale`) and clamps generated profiles to it (:meth:`Feasible.clamp`).
For a planar trajectory ``cv`` is zero and the region is a vertical band ``u_min <= u <= u_max``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from foldfab.errors import DesignError
from foldfab.geometry.reflection import check_polyline, as_3d, length_tolerance, planes


@dataclass(frozen=True)
class Feasible:
    """The half-planes ``c0 + cu·u + cv·v >= 0`` of a trajectory (one per segment between planes)."""

    c0: np.ndarray
    cu: np.ndarray
    cv: np.ndarray

    @classmethod
    def of(cls, trajectory) -> Feasible:
        """The region of ``trajectory`` (N, 2|3); a trajectory :func:`reflect` refuses raises its error."""
        trajectory = as_3d(trajectory)
        tol = length_tolerance(trajectory)
        check_polyline(trajectory, "trajectory", tol)
        return cls(*planes(trajectory, tol).limits())

    def lengths(self, points: np.ndarray) -> np.ndarray:
        """(J, K): segment lengths of the line elements of ``points`` (J, 2), offset included."""
        points = np.asarray(points, dtype=float).reshape(-1, 2)
        return self.c0 + np.multiply.outer(points[:, 0], self.cu) + np.multiply.outer(points[:, 1], self.cv)

    def min_scale(self, points: np.ndarray) -> float:
        """The smallest factor by which to scale the trajectory so every point is inside (0 if any will do).

        Scaling the trajectory scales ``c0`` and leaves ``cu``, ``cv`` (directions only) as they are."""
        points = np.asarray(points, dtype=float).reshape(-1, 2)
        need = -(np.multiply.outer(points[:, 0], self.cu) + np.multiply.outer(points[:, 1], self.cv)) / self.c0
        return float(max(need.max(initial=0.0), 0.0))

    def u_range(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The smallest and largest u at each height ``v`` (-inf, inf where unbounded; lo > hi where none)."""
        v = np.atleast_1d(np.asarray(v, dtype=float))
        rest = self.c0 + np.multiply.outer(v, self.cv)           # (n, K): cu·u >= -rest
        with np.errstate(divide="ignore", invalid="ignore"):
            bound = -rest / self.cu
        upper = np.where(self.cu < 0, bound, np.inf).min(axis=1, initial=np.inf)
        lower = np.where(self.cu > 0, bound, -np.inf).max(axis=1, initial=-np.inf)
        return lower, upper

    def clamp(self, points: np.ndarray, margin: float | np.ndarray = 0.0) -> np.ndarray:
        """``points`` (J, 2) with each u moved into the region at its height (v kept), so that every
        segment of its line element is at least ``margin`` mm long (one value, or one per segment)."""
        points = np.array(points, dtype=float).reshape(-1, 2)
        lower, upper = Feasible(self.c0 - margin, self.cu, self.cv).u_range(points[:, 1])
        if np.any(lower > upper):
            j = int(np.argmax(lower > upper))
            raise DesignError(f"profile point {j}: the trajectory leaves no room at height v={points[j, 1]:g}; "
                              "change the trajectory or the profile's heights")
        points[:, 0] = np.clip(points[:, 0], lower, upper)
        return points

    def polygon(self, box: tuple[float, float, float, float]) -> np.ndarray:
        """The region inside ``box`` (u0, v0, u1, v1) as a convex polygon (N, 2), counter-clockwise; empty if none."""
        u0, v0, u1, v1 = box
        poly = np.array([[u0, v0], [u1, v0], [u1, v1], [u0, v1]], float)
        for a, b, c in zip(self.c0, self.cu, self.cv):
            if len(poly) == 0:
                break
            poly = _clip(poly, a, b, c)
        return poly


def _clip(poly: np.ndarray, a: float, b: float, c: float) -> np.ndarray:
    """Sutherland-Hodgman: the part of convex ``poly`` where a + b·u + c·v >= 0."""
    side = a + poly @ np.array([b, c])
    out = []
    for i in range(len(poly)):
        p, q, sp, sq = poly[i], poly[(i + 1) % len(poly)], side[i], side[(i + 1) % len(poly)]
        if sp >= 0:
            out.append(p)
        if (sp >= 0) != (sq >= 0):
            out.append(p + (q - p) * (sp / (sp - sq)))
    return np.array(out, float).reshape(-1, 2)


SIZES = {"regular": ("radius",), "star": ("outer_radius", "inner_radius")}
"""The size parameters of each template (mm): scaling them all scales the trajectory."""
MAX_GROWTH = 4.0
"""A template is grown at most this many times to fit its profile; a profile that needs more
(a corner that turns by a degree or two leaves almost no room) keeps its error, which says why."""
SIZE_STEP = 0.5
"""mm: a template grown to fit its profile is rounded up to this step (the studio's slider step)."""
STAR_INNER = 0.6
"""A new star's inner radius, as a fraction of the radius at which its inner corners would lie on a
straight line between the outer ones (at least half the outer radius): a deep star, whose
corners turn far from straight, so that its mirrors leave the profile room."""


def _template(template: str, params: dict) -> np.ndarray:
    from foldfab.geometry import templates

    if template == "regular":
        return templates.regular(int(params["corners"]), float(params["radius"]))
    return templates.star(int(params["points"]), float(params["outer_radius"]), float(params["inner_radius"]))


def _fits(template: str, params: dict, points: np.ndarray) -> bool:
    try:
        return Feasible.of(_template(template, params)).min_scale(points) <= 1.0
    except DesignError:
        return False


def fit_template(template: str, params: dict, points: np.ndarray, changed: str = "template",
                 previous: float | None = None) -> tuple[dict, str]:
    """Template parameters close to ``params`` whose trajectory leaves room for every profile point
    (``points``, offset included), and a sentence saying what was changed ("" if nothing).

    ``changed`` names what the user just did: a size parameter moved from ``previous`` (a value
    that fitted) is clamped at the last value that fits on the way to the new one; a new
    template ("template", a new star gets a deep inner radius) or a new number of corners
    ("corners", "points") grows the whole template just enough.  A trajectory that no size fixes
    (an odd number of corners) is returned as it is: its error says why."""
    if template not in SIZES:
        return dict(params), ""
    params = dict(params)
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    if template == "star" and changed == "template":
        n = int(params["points"])
        params["inner_radius"] = round(float(params["outer_radius"]) * STAR_INNER * max(float(np.cos(np.pi / n)), 0.5), 3)
    try:
        scale = Feasible.of(_template(template, params)).min_scale(points)
    except DesignError:
        return params, ""
    if scale <= 1.0:
        return params, ""
    if changed in SIZES[template] and previous is not None and _fits(template, {**params, changed: previous}, points):
        good, bad = float(previous), float(params[changed])
        for _ in range(60):
            middle = 0.5 * (good + bad)
            if _fits(template, {**params, changed: middle}, points):
                good = middle
            else:
                bad = middle
        params[changed] = float(np.ceil(good * 1000) / 1000 if good > bad else np.floor(good * 1000) / 1000)
        if not _fits(template, params, points):
            params[changed] = good
        return params, f"{changed} stops at {params[changed]:g} mm: the profile needs the room"
    if scale > MAX_GROWTH:
        return params, (f"not grown: the profile needs a trajectory {scale:.3g} times larger; "
                        "change the profile or the template's corners")
    for _ in range(20):   # rounding up the radii separately may leave a star a little short
        params = {**params, **{key: float(np.ceil(float(params[key]) * scale / SIZE_STEP) * SIZE_STEP)
                               for key in SIZES[template]}}
        if _fits(template, params, points):
            break
        scale = 1.0 + SIZE_STEP / max(float(params[key]) for key in SIZES[template])
    sizes = ", ".join(f"{key} {params[key]:g} mm" for key in SIZES[template])
    return params, f"grew the trajectory to {sizes} so the profile fits its mirrors"
