"""The mirror-reflection construction of the paper, vectorized with numpy.

A profile polyline (u, v) is swept along the first trajectory direction into
parallel *line elements*; a mirror plane at every trajectory corner reflects
them, so line element ``j`` on trajectory segment ``k`` runs parallel to
``d_k``.  Everything follows from one observation: the composition of the
mirrors up to segment ``k`` maps the initial frame (travel ``d_0``, right
``r_0``, height ``h_0``) at ``T_0`` to a frame ``(d_k, r_k, h_k)`` at ``T_k``,
so line element ``j`` on segment ``k`` is the line

    L(x) = T_k + (x - σ_k)·d_k + u_j·r_k + v_j·h_k,

with ``x`` the distance travelled along the line element (the crease-pattern
abscissa) and ``σ_k`` the arc length of the trajectory up to ``T_k``.  Its
crossing with a plane of normal ``n`` through ``T_k`` is at

    x = σ_k − (u_j·(n·r_k) + v_j·(n·h_k)) / (n·d_k),

an outer product of the profile with per-plane coefficients: the whole grid of
crossings costs a few array operations.  Pure geometry: no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from foldfab.errors import DesignError

#: relative tolerance (of the design's size) below which a length counts as zero
REL_TOL = 1e-9

STRAIGHT_TURN = 1e-7
"""A trajectory corner that turns by less (radians) is straight: it has no mirror.  Its point
lies within 1e-7 of a segment's length of the straight line (0.1 µm on a metre, far below a
plotter's step), and its mirror would run so nearly along the path that only line elements
as near to the path could meet it; nearer still, the arithmetic cannot tell the mirror from
the path at all."""


@dataclass(frozen=True)
class Reflection:
    """The line-element grid of a design.

    ``x[j, k]`` is where line element ``j`` crosses plane ``k`` in crease-pattern
    coordinates, ``points[j, k]`` the same crossing in 3D; planes are the start
    plane (k = 0), the mirrors at the corners, and the end plane (k = K).
    """

    profile: np.ndarray       # (J, 2) profile points (u, v), offset applied
    arc: np.ndarray           # (J,) arc length along the profile: crease-pattern y
    trajectory: np.ndarray    # (K+1, 3) trajectory points after straight corners are dropped
    closed: bool
    corner_seam: bool         # closed, and the start point is a corner
    mirror_normals: np.ndarray  # (K+1, 3) plane normals: start, corners, end
    x: np.ndarray             # (J, K+1)
    points: np.ndarray        # (J, K+1, 3)
    corner_labels: tuple[str, ...]  # human names of the K+1 planes, for messages
    tolerance: float          # absolute length tolerance used (mm)

    @property
    def corners(self) -> int:
        """Number of mirror planes (corners with a turn), the seam included."""
        return len(self.trajectory) - 2 + int(self.corner_seam)

    @property
    def segment_lengths(self) -> np.ndarray:
        """(J, K) length of every segment of every line element."""
        return np.diff(self.x, axis=1)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _reflect(v: np.ndarray, n: np.ndarray) -> np.ndarray:
    return v - 2.0 * np.dot(v, n) * n


def check_polyline(points: np.ndarray, what: str, tol: float) -> None:
    if len(points) < 2:
        raise DesignError(f"{what}: needs at least 2 points, got {len(points)}")
    if not np.all(np.isfinite(points)):
        bad = int(np.argwhere(~np.isfinite(points))[0][0])
        raise DesignError(f"{what}: point {bad} is not a finite number: {points[bad].tolist()}")
    steps = np.linalg.norm(np.diff(points, axis=0), axis=1)
    if np.any(steps <= tol):
        i = int(np.argmax(steps <= tol))
        raise DesignError(f"{what}: points {i} and {i + 1} are the same point {points[i].tolist()}; remove the repeated point")


def _simplify_trajectory(points: np.ndarray) -> tuple[np.ndarray, list[int]]:
    """Drop straight corners (no turn, no mirror); reject reversals. Returns points and original indices."""
    d = _unit(np.diff(points, axis=0))
    turn = np.linalg.norm(d[1:] - d[:-1], axis=1)
    reversal = np.linalg.norm(d[1:] + d[:-1], axis=1) <= 1e-9
    if np.any(reversal):
        i = int(np.argmax(reversal)) + 1
        raise DesignError(f"trajectory: the path turns back on itself at point {i} {points[i].tolist()}; "
                          "a 180-degree turn has no mirror plane: remove or move that point")
    keep = np.concatenate([[True], turn > STRAIGHT_TURN, [True]])
    index = np.flatnonzero(keep)
    return points[keep], index.tolist()


@dataclass(frozen=True)
class Planes:
    """The planes of a trajectory and, per plane, the coefficients of the crossing formula.

    Line element (u, v) crosses plane ``k`` at ``x = sigma[k] - u·coef_u[k] - v·coef_v[k]``, so
    its segment ``k`` is ``c0[k] + cu[k]·u + cv[k]·v`` long (:meth:`limits`): one linear rule per
    segment, the rule :func:`reflect` checks and the studio shades (:mod:`foldfab.geometry.feasible`).
    """

    trajectory: np.ndarray    # (K+1, 3) without straight corners
    closed: bool
    corner_seam: bool
    directions: np.ndarray    # (K, 3)
    normals: np.ndarray       # (K+1, 3)
    frames_r: np.ndarray      # (K, 3)
    frames_h: np.ndarray      # (K, 3)
    sigma: np.ndarray         # (K+1,) arc length of the trajectory at each plane
    coef_u: np.ndarray        # (K+1,)
    coef_v: np.ndarray        # (K+1,)
    labels: tuple[str, ...]

    def limits(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(c0, cu, cv), each (K,): segment k of line element (u, v) is c0 + cu·u + cv·v long."""
        return np.diff(self.sigma), -np.diff(self.coef_u), -np.diff(self.coef_v)

    def turns(self) -> np.ndarray:
        """Degrees the path turns at each plane (0 at a start or end plane)."""
        d = self.directions
        ends = d[[-1, 0]] if self.corner_seam else np.zeros((2, 3))
        chords = np.linalg.norm(np.vstack([ends[1] - ends[0], d[1:] - d[:-1], ends[1] - ends[0]]), axis=1)
        return np.degrees(2 * np.arcsin(np.minimum(chords / 2, 1.0)))


def length_tolerance(*polylines: np.ndarray) -> float:
    """The absolute tolerance (mm) below which a length counts as zero, for polylines of this size."""
    return REL_TOL * max([float(np.ptp(p, axis=0).max(initial=0.0)) for p in polylines if p.size] + [1.0])


def as_3d(trajectory) -> np.ndarray:
    """A trajectory (N, 2|3) as float (N, 3) points (z = 0 for a planar one)."""
    trajectory = np.asarray(trajectory, dtype=float)
    if trajectory.ndim == 2 and trajectory.shape[1] == 2:
        trajectory = np.column_stack([trajectory, np.zeros(len(trajectory))])
    return trajectory


def planes(trajectory: np.ndarray, tol: float) -> Planes:
    """The planes of a checked (N, 3) ``trajectory`` (see :func:`reflect`); ``tol`` from :func:`length_tolerance`."""
    closed = bool(np.linalg.norm(trajectory[-1] - trajectory[0]) <= tol)  # an SVG path's relative moves miss by 1e-15
    if closed:
        trajectory = np.concatenate([trajectory[:-1], trajectory[:1]])
    traj, original = _simplify_trajectory(trajectory)

    seg = np.diff(traj, axis=0)
    lengths = np.linalg.norm(seg, axis=1)
    d = seg / lengths[:, None]
    sigma = np.concatenate([[0.0], np.cumsum(lengths)])
    K = len(d)

    z = np.array([0.0, 0.0, 1.0])
    right = np.cross(d[0], z)
    if np.linalg.norm(right) < 1e-12:
        raise DesignError("trajectory: the first segment is vertical, so 'right of the travel direction' "
                          "is undefined; start the trajectory with a segment that is not vertical")
    r0 = right / np.linalg.norm(right)
    h0 = np.cross(r0, d[0])

    mirror = _unit(d[:-1] - d[1:])  # normals at the K-1 interior corners
    corner_seam = closed and np.linalg.norm(d[-1] - d[0]) > STRAIGHT_TURN
    if closed and np.linalg.norm(d[-1] + d[0]) <= 1e-9:
        raise DesignError(f"trajectory: the path turns back on itself at its start point {trajectory[0].tolist()}; "
                          "a 180-degree turn has no mirror plane: move the start point")
    seam = _unit(d[-1] - d[0]) if corner_seam else d[0]
    normals = np.vstack([seam, mirror, seam if closed else d[-1]])

    # Frames of every segment: reflect (r, h) at each mirror in turn.
    frames_r = np.empty((K, 3))
    frames_h = np.empty((K, 3))
    r, h = r0, h0
    for k in range(K):
        if k:
            r, h = _reflect(r, mirror[k - 1]), _reflect(h, mirror[k - 1])
        frames_r[k], frames_h[k] = r, h

    labels = _plane_labels(traj, original, closed, corner_seam)
    if closed:
        _check_closure(frames_r[-1], frames_h[-1], r0, h0, seam if corner_seam else None, len(mirror) + int(corner_seam))

    # Plane k uses the frame of segment min(k, K-1): a mirror gives the same crossing from either side.
    f = np.minimum(np.arange(K + 1), K - 1)
    nd = np.einsum("ij,ij->i", normals, d[f])
    coef_u = np.einsum("ij,ij->i", normals, frames_r[f]) / nd
    coef_v = np.einsum("ij,ij->i", normals, frames_h[f]) / nd
    return Planes(traj, closed, bool(corner_seam), d, normals, frames_r, frames_h, sigma, coef_u, coef_v, labels)


def reflect(profile: np.ndarray, trajectory: np.ndarray) -> Reflection:
    """Build the line-element grid for ``profile`` (J, 2) and ``trajectory`` (N, 2|3).

    Raises :class:`DesignError` for an invalid design: too few or repeated
    points, an odd number of corners on a closed trajectory, a closed 3D
    trajectory that does not close, or a negative segment length.
    """
    profile = np.asarray(profile, dtype=float)
    trajectory = as_3d(trajectory)
    tol = length_tolerance(trajectory, profile)
    check_polyline(profile, "profile", tol)
    check_polyline(trajectory, "trajectory", tol)
    p = planes(trajectory, tol)
    traj, d, sigma, K = p.trajectory, p.directions, p.sigma, len(p.directions)
    f = np.minimum(np.arange(K + 1), K - 1)
    u, v = profile[:, 0], profile[:, 1]
    x = sigma[None, :] - np.multiply.outer(u, p.coef_u) - np.multiply.outer(v, p.coef_v)

    seglen = np.diff(x, axis=1)
    negative = seglen < -tol
    if np.any(negative):
        j, k = map(int, np.argwhere(negative)[0])
        raise DesignError(_negative_message(j, k, profile, p, seglen[j, k]))
    zero = np.abs(seglen) <= tol
    if np.any(zero):
        # Snap zero-length segments exactly, so their end points coincide.
        x = x[:, :1] + np.concatenate([np.zeros((len(x), 1)), np.cumsum(np.where(zero, 0.0, seglen), axis=1)], axis=1)

    offset = x - sigma[None, :]
    points = (traj[None, :, :] + offset[:, :, None] * d[f][None]
              + u[:, None, None] * p.frames_r[f][None] + v[:, None, None] * p.frames_h[f][None])
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(profile, axis=0), axis=1))])
    return Reflection(profile, arc, traj, p.closed, p.corner_seam, p.normals, x, points, p.labels, tol)


def _plane_labels(traj: np.ndarray, original: list[int], closed: bool, corner_seam: bool) -> tuple[str, ...]:
    def at(i: int) -> str:
        p = traj[i]
        coords = ", ".join(f"{c:g}" for c in (p if p[2] != 0 else p[:2]))
        return f"trajectory point {original[i]} ({coords})"

    inner = [f"the mirror at {at(i)}" for i in range(1, len(traj) - 1)]
    if closed and corner_seam:
        first = last = f"the seam mirror at {at(0)}"
    elif closed:
        first = last = f"the seam at {at(0)}"
    else:
        first, last = f"the start plane at {at(0)}", f"the end plane at {at(len(traj) - 1)}"
    return (first, *inner, last)


def _check_closure(r_end, h_end, r0, h0, seam_normal, corners: int) -> None:
    if corners % 2:
        raise DesignError(f"trajectory: a closed trajectory needs an even number of corners, this one has {corners}: "
                          "every mirror flips the paper, so an odd count cannot meet itself at the seam; "
                          "add or remove a corner")
    if seam_normal is not None:
        r_end, h_end = _reflect(r_end, seam_normal), _reflect(h_end, seam_normal)
    tol = 1e-9 + 1e-12 * corners  # each reflection rounds a little: 1.2e-9 after 100,000 of them
    if np.linalg.norm(r_end - r0) > tol or np.linalg.norm(h_end - h0) > tol:
        angle = np.degrees(np.arctan2(np.dot(np.cross(r0, r_end), np.cross(r0, h0)), np.dot(r0, r_end)))
        raise DesignError(f"trajectory: this closed 3D trajectory does not close: its mirrors turn the profile by "
                          f"{abs(angle):.3g} degrees about the seam; make the trajectory planar or symmetric so the turns cancel")


SHALLOW_TURN = 5.0
"""Degrees: a mirror at a corner that turns the path by less runs so nearly along the path
that an error it causes says so (the point may belong on a straight line)."""


def _negative_message(j: int, k: int, profile: np.ndarray, p: Planes, length: float) -> str:
    u, v = profile[j]
    c0, cu, cv = (a[k] for a in p.limits())
    labels, turns = p.labels, p.turns()
    if abs(cu) > 1e-12:
        limit = -(c0 + cv * v) / cu
        advice = (f"reduce u of profile point {j} (or [profile].offset[0]) to at most {limit:.4g} mm" if cu < 0 else
                  f"increase u of profile point {j} (or [profile].offset[0]) to at least {limit:.4g} mm")
    elif abs(cv) > 1e-12:
        limit = -(c0 + cu * u) / cv
        advice = (f"reduce v of profile point {j} (or [profile].offset[1]) to at most {limit:.4g} mm" if cv < 0 else
                  f"increase v of profile point {j} (or [profile].offset[1]) to at least {limit:.4g} mm")
    else:  # pragma: no cover - a negative length always depends on u or v
        advice = "enlarge the trajectory"
    shallow = [m for m in (k, k + 1) if 0 < turns[m] < SHALLOW_TURN]
    hint = "".join(f"; {labels[m]} turns the path by only {turns[m]:.2g} degrees, so it runs nearly along "
                   "the path: if that point belongs on a straight line, remove it" for m in shallow)
    return (f"line element {j} (profile point {j} at u={u:g}, v={v:g}) meets {labels[k + 1]} before {labels[k]}: "
            f"its segment {k} would be {length:.4g} mm long; {advice}, or enlarge the trajectory{hint}")
