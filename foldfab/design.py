"""A design: a job's polylines turned into the reflection grid and crease pattern.

This is the one place that goes from a validated :class:`~foldfab.job.Job` to
geometry; the command line, the exporters, fabrication and the studio all call
:func:`build_design`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from foldfab.geometry.crease_pattern import CreasePattern, build_crease_pattern
from foldfab.errors import DesignError, FoldfabError
from foldfab.job import Job, SvgSource
from foldfab.limits import MAX_FACES
from foldfab.geometry.reflection import Reflection, reflect


@dataclass(frozen=True)
class Design:
    """A built design and what the checks found."""

    job: Job
    grid: Reflection
    crease_pattern: CreasePattern
    penetrations: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.int64))
    warnings: tuple[str, ...] = ()
    marks: tuple[np.ndarray, ...] = ()   # strokes (N, 2) on the crease pattern: a split piece's match marks


def _svg_points(source: SvgSource, where: str) -> np.ndarray:
    from foldfab.geometry.svg_input import read_svg_polyline

    return read_svg_polyline(source.file, source.path, source.samples, source.tolerance, where)


def profile_points(job: Job) -> np.ndarray:
    """The profile polyline (J, 2) in mm with the job's offset added."""
    spec = job.profile
    if spec.points is not None:
        points = np.array(spec.points, dtype=float)
    else:
        points = _svg_points(spec.svg, f"{job.path}: [profile].svg")
    return points + np.array(spec.offset)


def trajectory_points(job: Job) -> np.ndarray:
    """The trajectory polyline (N, 3) in mm: a template, the given points, or an SVG path."""
    from foldfab.geometry import templates

    spec = job.trajectory
    if spec.template == "regular":
        return templates.regular(int(spec.params["corners"]), spec.params["radius"])
    if spec.template == "star":
        return templates.star(int(spec.params["points"]), spec.params["outer_radius"], spec.params["inner_radius"])
    if spec.svg is not None:
        pts = _svg_points(spec.svg, f"{job.path}: [trajectory].svg")
    else:
        pts = np.array(spec.points, dtype=float)
    if pts.shape[1] == 2:
        pts = np.column_stack([pts, np.zeros(len(pts))])
    return pts


LIMIT_ADVICE = ("use fewer points (for an SVG: fewer [profile].samples or a larger tolerance), or set "
                "[design].max_faces = N in the job or pass --max-faces N to build it anyway")
"""How to raise :data:`MAX_FACES` (the studio says its own)."""


def check_faces(profile: np.ndarray, trajectory: np.ndarray, glue_tab: bool, limit: int, advice: str) -> None:
    """Refuse, before anything is built, a design of more than ``limit`` faces (``advice``: how
    to allow more).

    Every profile segment meets every trajectory segment, and a glue tab, in one face, so the
    count is known from the polylines alone (straight trajectory corners merge later: this may
    count a few too many, never too few)."""
    columns = max(len(trajectory) - 1, 0) + glue_tab
    faces = max(len(profile) - 1, 0) * columns
    if faces > limit:
        tab = " and a glue tab" if glue_tab else ""
        raise DesignError(f"the design has {faces:,} faces ({len(profile) - 1:,} profile segments x "
                          f"{len(trajectory) - 1:,} trajectory segments{tab}), more than the limit of {limit:,}; "
                          + advice)


def build_design(job: Job, *, check_penetration: bool = True, allow_penetration: bool = False,
                 max_faces: int | None = None, limit_advice: str = LIMIT_ADVICE) -> Design:
    """Build the design of ``job``; penetration is an error unless ``allow_penetration``.

    A design of more faces than ``max_faces`` (default: the job's ``[design].max_faces``,
    else :data:`MAX_FACES`) is refused before it is built, with ``limit_advice`` saying how
    to allow it.  Geometry errors are reported against the job file, naming the table they
    come from.
    """
    limit = max_faces if max_faces is not None else job.max_faces or MAX_FACES
    try:
        profile, trajectory = profile_points(job), trajectory_points(job)
        check_faces(profile, trajectory, job.crease.glue_tab > 0, limit, limit_advice)
        grid = reflect(profile, trajectory)
        cp = build_crease_pattern(grid, job.crease.flat_angle, job.crease.glue_tab)
    except DesignError as exc:
        raise DesignError(f"{job.path}: {exc}") from None
    penetrations = np.zeros((0, 2), np.int64)
    warnings: list[str] = []
    if check_penetration:
        from foldfab.geometry.penetration import find_penetrations

        penetrations = find_penetrations(cp)
        if len(penetrations):
            message = penetration_message(cp, penetrations)
            if not allow_penetration:
                raise DesignError(f"{job.path}: {message}; change the design, or pass --allow-penetration to build it anyway")
            warnings.append(message)
    return Design(job, grid, cp, penetrations, tuple(warnings))


def penetration_message(cp: CreasePattern, pairs: np.ndarray, limit: int = 5) -> str:
    """One line naming the intersecting faces by (profile segment, trajectory segment)."""
    names = [f"face {a} (profile segment {cp.face_grid[a][0]}, trajectory segment {cp.face_grid[a][1]}) "
             f"and face {b} (profile segment {cp.face_grid[b][0]}, trajectory segment {cp.face_grid[b][1]})"
             for a, b in pairs[:limit].tolist()]
    more = f" and {len(pairs) - limit} more pairs" if len(pairs) > limit else ""
    return f"penetration: {len(pairs)} pair(s) of faces of the folded model intersect: " + "; ".join(names) + more


def summary(design: Design) -> dict:
    """The numbers ``foldfab design`` prints: counts, crease lengths, sheet size, warnings."""
    cp = design.crease_pattern
    lengths = cp.edge_lengths
    creases = {}
    for kind, label in (("M", "mountain"), ("V", "valley"), ("F", "flat"), ("B", "border")):
        mask = cp.assignment == kind
        creases[label] = {"count": int(mask.sum()), "length_mm": round(float(lengths[mask].sum()), 3)}
    width, height = cp.sheet_size
    return {
        "name": design.job.name,
        "job": str(design.job.path),
        "closed": design.grid.closed,
        "corners": design.grid.corners,
        "line_elements": int(design.grid.x.shape[0]),
        "faces": int(len(cp.faces)),
        "vertices": int(len(cp.vertices)),
        "creases": creases,
        "sheet_mm": [round(width, 3), round(height, 3)],
        "penetrations": int(len(design.penetrations)),
        "warnings": list(design.warnings),
    }


def generated_profile(job: Job, kind: str, **params) -> np.ndarray:
    """New profile points (J, 2), without the offset, from a generator of
    :mod:`foldfab.geometry.profiles` (``params``: amplitude, period, count, height, passes), clamped to
    where ``job``'s trajectory leaves them room: the studio's profile tools and ``foldfab profile``."""
    from foldfab.geometry.feasible import Feasible
    from foldfab.geometry.profiles import generate

    offset = np.array(job.profile.offset)
    try:
        return generate(kind, Feasible.of(trajectory_points(job)), offset, profile_points(job) - offset,
                        glue_tab=job.crease.glue_tab, **params)
    except DesignError as exc:
        raise DesignError(f"{job.path}: {exc}") from None


def load_design(path, **kwargs) -> Design:
    """Read a job file and build its design."""
    from foldfab.job import load_job

    return build_design(load_job(path), **kwargs)


__all__ = ["Design", "build_design", "load_design", "summary", "profile_points", "trajectory_points", "generated_profile",
           "penetration_message", "FoldfabError"]
