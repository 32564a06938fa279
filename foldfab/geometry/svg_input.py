"""Read one path of an SVG file as a polyline in millimetres.

The page's bottom-left corner is the origin, x (or the profile's u) runs to the
right and y (or v) runs up: SVG's y-down user units are flipped and scaled to mm
with the file's own width/height, viewBox and preserveAspectRatio, by the SVG
viewBox-to-viewport rules: the page is width x height (a missing one follows
from the viewBox's aspect ratio; both missing, the viewBox size in px), and the
viewBox is fitted into it uniformly (``meet``, the default, or ``slice``) at the
given alignment (default ``xMidYMid``), or stretched with ``none``; without a
viewBox a user unit is a px.  Nothing is clipped: with ``slice`` a path may
reach past the page edges.  Straight segments keep their exact end points;
curves are sampled by a maximum chord error or, with ``samples``, by a fixed
number of points spaced evenly along the arc.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from foldfab.errors import FoldfabError
from foldfab.limits import LENGTH_LIMIT

_UNIT_MM = {"": 25.4 / 96, "px": 25.4 / 96, "mm": 1.0, "cm": 10.0, "in": 25.4,
            "pt": 25.4 / 72, "pc": 25.4 / 6, "q": 0.25}
DEFAULT_TOLERANCE = 0.05  # mm chord error when neither samples nor tolerance is given


def _length_mm(value: str | None, where: str) -> float | None:
    if value is None:
        return None
    match = re.fullmatch(r"\s*([0-9.eE+-]+)\s*([a-zA-Z%]*)\s*", value)
    try:
        number = float(match.group(1)) if match else None
    except ValueError:  # "e", "1-2": the pattern lets them through
        number = None
    if number is None or not np.isfinite(number) or match.group(2).lower() not in _UNIT_MM:
        raise FoldfabError(f"{where}: unsupported SVG length {value!r}; use a number with mm, cm, in, pt, pc or px")
    return number * _UNIT_MM[match.group(2).lower()]


_ALIGN = {f"x{x}Y{y}": (fx, fy) for x, fx in (("Min", 0.0), ("Mid", 0.5), ("Max", 1.0))
          for y, fy in (("Min", 0.0), ("Mid", 0.5), ("Max", 1.0))}


def _aspect(value: str | None, where: str) -> tuple[tuple[float, float] | None, bool]:
    """preserveAspectRatio as ((x, y) alignment fractions or None for ``none``, slice)."""
    if value is None:
        return _ALIGN["xMidYMid"], False
    words = value.split()
    if words[:1] == ["defer"]:  # SVG 1.1: only meaningful on <image>, ignored elsewhere
        words = words[1:]
    if (1 <= len(words) <= 2 and (words[0] == "none" or words[0] in _ALIGN)
            and words[1:] in ([], ["meet"], ["slice"])):
        return _ALIGN.get(words[0]), words[1:] == ["slice"]
    raise FoldfabError(f"{where}: preserveAspectRatio {value!r} is not an alignment; use none or "
                       "x(Min|Mid|Max)Y(Min|Mid|Max) such as xMidYMid, optionally followed by meet or slice")


def _page_transform(root, where: str) -> tuple[float, float, float, float, float, float]:
    """(scale_x, scale_y, min_x, bottom, left, base) mapping user units to mm on the page.

    A user point (x, y) lands at ``(left + (x - min_x) * scale_x, base + (bottom - y) * scale_y)``
    mm: ``min_x`` and ``bottom`` are the viewBox's left and bottom edges (user units) and
    ``left``/``base`` where those edges land on the page (mm from its left and bottom edges;
    not 0 when preserveAspectRatio aligns a viewBox of another aspect ratio inside the page).
    """
    width = _length_mm(root.get("width"), f"{where}: width")
    height = _length_mm(root.get("height"), f"{where}: height")
    for name, size in (("width", width), ("height", height)):
        if size is not None and size <= 0:
            raise FoldfabError(f"{where}: {name} {root.get(name)!r} must be greater than 0")
    view_box = root.get("viewBox")
    if view_box:
        try:
            vx, vy, vw, vh = (float(v) for v in re.split(r"[\s,]+", view_box.strip()))
        except ValueError:
            raise FoldfabError(f"{where}: viewBox {view_box!r} is not four numbers") from None
        if not np.all(np.isfinite([vx, vy, vw, vh])):
            raise FoldfabError(f"{where}: viewBox {view_box!r} is not four finite numbers")
        if vw <= 0 or vh <= 0:
            raise FoldfabError(f"{where}: viewBox {view_box!r} has no area")
        align, slice_ = _aspect(root.get("preserveAspectRatio"), where)
        if width is None and height is None:
            width, height = vw * _UNIT_MM["px"], vh * _UNIT_MM["px"]
        elif width is None:
            width = height * vw / vh
        elif height is None:
            height = width * vh / vw
        sx, sy = width / vw, height / vh
        if align is None:  # none: stretch the viewBox onto the page, each axis on its own
            return sx, sy, vx, vy + vh, 0.0, 0.0
        scale = max(sx, sy) if slice_ else min(sx, sy)
        fx, fy = align
        # SVG aligns y downwards from the page top: YMin puts the viewBox top on the page top.
        left = fx * (width - vw * scale)
        base = (1.0 - fy) * (height - vh * scale)
        return scale, scale, vx, vy + vh, left, base
    unit = _UNIT_MM["px"]
    page_h = height / unit if height else 0.0
    return unit, unit, 0.0, page_h, 0.0, 0.0


def _to_segment(q: complex, p0: complex, p1: complex) -> float:
    """Distance from ``q`` to the segment p0-p1 (the chord, not its infinite line)."""
    chord = p1 - p0
    n2 = chord.real ** 2 + chord.imag ** 2  # tested itself: a tiny chord's square can underflow to 0
    s = ((q - p0) * np.conj(chord)).real / n2 if n2 > 0 else 0.0
    return abs(q - (p0 + min(max(s, 0.0), 1.0) * chord))


def _svgpathtools():
    """The svgpathtools package, loaded without loading scipy.integrate.

    svgpathtools.path imports ``scipy.integrate.quad`` as it loads, for arc lengths
    that foldfab never asks for (samples are spaced by :func:`_evenly`); that import
    costs 80-90 ms, a sixth of a paper-scale export.  svgpathtools supports running
    without scipy, so the import is made to fail once, and svgpathtools is then handed
    a ``quad`` that imports scipy's on first use: anyone else using svgpathtools in
    the process gets the same lengths as always.
    """
    import sys

    if "svgpathtools" not in sys.modules and "scipy.integrate" not in sys.modules:
        sys.modules["scipy.integrate"] = None  # `from scipy.integrate import ...` raises ImportError
        try:
            import svgpathtools.path as module
        except ImportError:  # a svgpathtools that needs scipy.integrate: load it as usual below
            pass
        else:
            if not getattr(module, "_quad_available", True):
                module.quad, module._quad_available = _quad, True
        finally:
            del sys.modules["scipy.integrate"]
    import svgpathtools

    return svgpathtools


def _quad(*args, **kwargs):
    """scipy.integrate.quad, imported when first called."""
    from scipy.integrate import quad

    return quad(*args, **kwargs)


ARC_CHORDS = 4096  # chords per piece that measure arc length for ``samples``


def _evenly(path, samples: int) -> np.ndarray:
    """``samples`` points of ``path`` evenly spaced by arc length, both ends included (complex).

    Arc length is measured along ``ARC_CHORDS`` chords per piece, at a relative error
    of about 1e-8 on smooth curves, and each point is placed on the curve itself at its
    interpolated parameter.  svgpathtools' ``ilength`` would integrate with scipy per
    point: 0.24 s for 400 points of the example vase.
    """
    dense_t = np.linspace(0.0, 1.0, ARC_CHORDS + 1)
    dense = np.concatenate([seg.point(dense_t) for seg in path])
    chords = np.abs(np.diff(dense))
    chords[ARC_CHORDS::ARC_CHORDS + 1] = 0.0  # from one piece's end to the next one's start
    arc = np.concatenate([[0.0], np.cumsum(chords)])
    along = np.linspace(0.0, arc[-1], samples)
    at = np.clip(np.searchsorted(arc, along, side="right") - 1, 0, len(arc) - 2)
    gap = arc[at + 1] - arc[at]
    frac = np.divide(along - arc[at], gap, out=np.zeros_like(along), where=gap > 0)
    piece, step = np.divmod(at, ARC_CHORDS + 1)
    t = np.minimum((step + frac) / ARC_CHORDS, 1.0)
    points = np.empty(samples, dtype=complex)
    for k in np.unique(piece):
        chosen = piece == k
        points[chosen] = path[int(k)].point(t[chosen])
    points[0], points[-1] = path[0].start, path[-1].end
    return points


def _sample(path, samples: int | None, tolerance: float, scale: float) -> np.ndarray:
    """Points along an svgpathtools Path, in user units (complex)."""
    if samples is not None:
        return _evenly(path, samples)
    line = _svgpathtools().Line
    points = [path[0].start]
    tol = tolerance / scale
    for seg in path:
        if isinstance(seg, line):
            points.append(seg.end)
            continue
        stack = [(0.0, 1.0)]
        out = []
        while stack:
            t0, t1 = stack.pop()
            p0, p1 = seg.point(t0), seg.point(t1)
            if hasattr(seg, "bpoints"):  # a Bezier piece lies in the convex hull of its control points
                probes = seg.cropped(t0, t1).bpoints()[1:-1]
            else:
                probes = [seg.point(t) for t in np.linspace(t0, t1, 5)[1:-1]]
            err = max(_to_segment(q, p0, p1) for q in probes)
            if err > tol and t1 - t0 > 1e-6:
                tm = 0.5 * (t0 + t1)
                stack.append((tm, t1))
                stack.append((t0, tm))
            else:
                out.append(p1)
        points.extend(out)
    return np.array(points)


def read_svg_polyline(file: Path, path: str | int = 0, samples: int | None = None,
                      tolerance: float | None = None, where: str = "") -> np.ndarray:
    """The chosen path of ``file`` as an (N, 2) array in mm, y up from the page bottom."""
    import io
    from xml.etree.ElementTree import ParseError

    from foldfab.files import SVG_LIMIT, read_bytes

    where = where or str(file)
    data = read_bytes(file, "SVG file", SVG_LIMIT)
    try:
        doc = _svgpathtools().Document(io.BytesIO(data))
    except ParseError as exc:
        raise FoldfabError(f"{file}: cannot read SVG: {exc}") from None
    root = doc.tree.getroot()
    order = {id(el): i for i, el in enumerate(root.iter())}
    try:
        with np.errstate(all="ignore"):  # a huge transform overflows in svgpathtools: the points are checked below
            drawn = doc.paths()
    except (ValueError, IndexError, TypeError, ZeroDivisionError) as exc:  # svgpathtools' parser and transforms
        raise FoldfabError(f"{file}: cannot read its paths: {exc}; check the d attributes (and transforms) "
                           "in an SVG editor") from None
    paths = sorted((p for p in drawn if len(p) > 0), key=lambda p: order.get(id(p.element), 0))
    if isinstance(path, str):
        chosen = [p for p in paths if p.element.get("id") == path]
        if not chosen:
            ids = [p.element.get("id") for p in paths if p.element.get("id")]
            raise FoldfabError(f"{where}: no path with id {path!r} in {file}; ids there: {', '.join(ids) or 'none'}")
        chosen_path = chosen[0]
    else:
        if path >= len(paths):
            raise FoldfabError(f"{where}: path index {path} out of range: {file} has {len(paths)} drawable path(s)")
        chosen_path = paths[path]
    if not chosen_path.iscontinuous():
        raise FoldfabError(f"{where}: the chosen path of {file} has several pieces (subpaths); use one continuous path")
    sx, sy, min_x, bottom, left, base = _page_transform(root, f"{file}")
    # complex: svgpathtools reads d="Z" (a close with no point before it) as a line to None, here NaN
    ends = np.array([[seg.start, seg.end] for seg in chosen_path], dtype=complex)
    if not np.all(np.isfinite(ends)):
        raise FoldfabError(f"{where}: the chosen path of {file} has a point that is not a finite number (or none: a Z before any M?); "
                           "check its d attribute")

    def to_mm(points: np.ndarray) -> np.ndarray:
        return np.column_stack([left + (points.real - min_x) * sx, base + (bottom - points.imag) * sy])

    try:
        with np.errstate(all="ignore"):  # overflow gives inf or NaN, refused just below
            x0, x1, y0, y1 = chosen_path.bbox()
        reach = float(np.abs(to_mm(np.array([complex(x0, y0), complex(x1, y1)]))).max())
    except OverflowError:  # a curve's extremes are found with Python floats, whose squares overflow
        reach = math.inf
    if not reach <= LENGTH_LIMIT:  # NaN too
        raise FoldfabError(f"{where}: the chosen path of {file} reaches beyond ±{LENGTH_LIMIT:,.0f} mm; "
                           "check the file's width, height and viewBox")
    pts = _sample(chosen_path, samples, tolerance or DEFAULT_TOLERANCE, max(sx, sy))
    out = to_mm(pts)
    keep = np.ones(len(out), bool)
    keep[1:] = np.any(np.abs(np.diff(out, axis=0)) > 1e-12, axis=1)
    return out[keep]
