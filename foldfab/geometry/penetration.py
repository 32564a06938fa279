"""Penetration: do faces of the folded 3D model cross (its mesh file: :mod:`foldfab.formats.mesh`)?

Penetration means two non-adjacent faces of the folded model intersect, which
paper cannot do.  The check is a uniform-grid broad phase over face boxes
followed by an exact separating-axis test, all vectorized; faces that share a
vertex in 3D (after welding, so the seam of a closed design counts) are
adjacent and never reported, nor are glue-tab faces, which lie on the sheet by
design.  Touching (within a tolerance) is not penetration.
"""

from __future__ import annotations

import math

import numpy as np

from foldfab.geometry.crease_pattern import CreasePattern


def _weld(points: np.ndarray, tol: float) -> np.ndarray:
    """An id per point; points within ``tol`` of one another (on a grid) share it."""
    keys = np.round(points / tol).astype(np.int64)
    order = np.lexsort(keys.T[::-1])
    step = np.any(np.diff(keys[order], axis=0) != 0, axis=1)
    ids = np.empty(len(points), np.int64)
    ids[order] = np.concatenate([[0], np.cumsum(step)])
    return ids


CHUNK = 1 << 20
"""Box-cell entries worked out at a time in :func:`candidate_pairs` (bounds its temporary arrays)."""


def candidate_pairs(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Pairs (i < j) of 3D boxes that share a cell of a uniform grid sized to the boxes: every
    two boxes that overlap are among them."""
    n = len(lo)
    # One cell size per axis: the boxes' median extent along it.  Thin, long faces (a finely
    # sampled profile) would crowd cubic cells sized to their length with millions of pairs.
    # (Reduced along contiguous rows of the transposes: numpy is slow along a 3-wide axis.)
    lo_t, hi_t = np.ascontiguousarray(lo.T), np.ascontiguousarray(hi.T)
    floor = max(float((hi_t.max(axis=1) - lo_t.min(axis=1)).max()) * 1e-6, 1e-12)
    cell = np.maximum(np.median(hi_t - lo_t, axis=1), floor)
    del lo_t, hi_t
    # counted from the lowest corner, no cell number exceeds a million (the floor): far from the
    # origin, boxes that are all one point would otherwise divide past 64 bits
    origin = lo.min(axis=0)
    while True:
        c_lo = np.floor((lo - origin) / cell).astype(np.int64)
        c_hi = np.floor((hi - origin) / cell).astype(np.int64)
        span = c_hi - c_lo + 1
        counts = span.prod(axis=1)
        if counts.sum() <= 16 * n + 1024:
            break
        cell *= 1.5
    base = c_lo.min(axis=0)
    dims = c_hi.max(axis=0) - base + 1
    c_lo -= base
    keys, owners = _cell_entries(c_lo, span, counts, dims)
    if math.prod(dims.tolist()) * n < 1 << 62:  # cell and box as one number: sorting values is quicker
        entries = np.sort(keys * n + owners)  # each cell's boxes in increasing order
        keys = entries // n
        owners = entries - keys * n
        del entries
    else:
        order = np.argsort(keys, kind="stable")   # stable: each cell's boxes stay in increasing order
        keys, owners = keys[order], owners[order]
        del order
    # Only cells holding two boxes or more make pairs: their runs of entries, one after another.
    start = np.flatnonzero(np.concatenate([[True], keys[1:] != keys[:-1]]))
    size = np.diff(start, append=len(keys))
    del keys
    start, size = start[size > 1], size[size > 1]
    place = np.arange(int(size.sum())) - np.repeat(np.cumsum(size) - size, size)  # within its run
    owners = owners[np.repeat(start, size) + place]
    size = np.repeat(size, size)
    pairs = []
    shift = 1
    idx = np.flatnonzero(place + 1 < size)
    while len(idx):
        # a box is in a cell once and the runs are in increasing order: every pair is (smaller, larger)
        pairs.append(owners[idx].astype(np.int64) * n + owners[idx + shift])
        shift += 1
        idx = idx[place[idx] + shift < size[idx]]
    if not pairs:
        return np.zeros((0, 2), np.int64)
    return _decode_pairs(np.concatenate(pairs), n)


def _cell_entries(c_lo: np.ndarray, span: np.ndarray, counts: np.ndarray, dims: np.ndarray) -> tuple:
    """The cell (a key) and the box of every box-cell entry, boxes in order: box i (its lowest cell
    ``c_lo[i]``, ``span[i]`` cells along each axis) covers ``counts[i]`` cells.  Worked out
    :data:`CHUNK` entries at a time."""
    keys, owners = [], []
    ends = np.cumsum(counts)
    first = 0
    while first < len(counts):
        last = max(int(np.searchsorted(ends, ends[first] - counts[first] + CHUNK, side="right")), first + 1)
        part = slice(first, last)
        sizes = counts[part]
        owner = np.repeat(np.arange(first, last, dtype=np.int32), sizes)
        local = np.arange(int(sizes.sum())) - np.repeat(np.cumsum(sizes) - sizes, sizes)

        def each(values: np.ndarray) -> np.ndarray:  # a value per box, repeated for its entries
            return np.repeat(values[part], sizes)
        sy, sz = each(span[:, 1]), each(span[:, 2])
        key = each(c_lo[:, 0]) + local // (sy * sz)
        key = key * dims[1] + each(c_lo[:, 1]) + (local // sz) % sy
        keys.append(key * dims[2] + each(c_lo[:, 2]) + local % sz)
        owners.append(owner)
        first = last
    return np.concatenate(keys), np.concatenate(owners)


def _decode_pairs(keys: np.ndarray, n: int) -> np.ndarray:
    """Distinct pairs from their keys ``i * n + j``, as rows (i, j)."""
    keys.sort()  # sort-based: np.unique hashes, far slower here
    keys = keys[np.concatenate([[True], keys[1:] != keys[:-1]])] if len(keys) else keys
    return np.column_stack([keys // n, keys % n])


def _unique_pairs(pairs: np.ndarray, n: int) -> np.ndarray:
    """Distinct rows of an (P, 2) array of ids below ``n``."""
    return _decode_pairs(pairs[:, 0] * np.int64(n) + pairs[:, 1], n)


def _triangles_intersect(a: np.ndarray, b: np.ndarray, eps: float) -> np.ndarray:
    """Separating-axis test for triangle pairs (P, 3, 3): True where they overlap by more than ``eps``."""
    ea = np.roll(a, -1, axis=1) - a
    eb = np.roll(b, -1, axis=1) - b
    axes = np.concatenate([np.cross(ea[:, 0], ea[:, 1])[:, None], np.cross(eb[:, 0], eb[:, 1])[:, None],
                           np.cross(ea[:, :, None], eb[:, None, :]).reshape(-1, 9, 3)], axis=1)
    norm = np.linalg.norm(axes, axis=2)
    scale = np.maximum(np.abs(a).max(axis=(1, 2)), np.abs(b).max(axis=(1, 2)))[:, None] + 1.0
    valid = norm > 1e-12 * scale ** 2
    axes = axes / np.where(valid, norm, 1.0)[..., None]
    pa = np.einsum("pkd,pvd->pkv", axes, a)
    pb = np.einsum("pkd,pvd->pkv", axes, b)
    # Penetration depth along each axis: how far one triangle must move to clear the other.
    # (Not the length of the intervals' overlap, which is 0 on a triangle's own normal.)
    depth = np.minimum(pa.max(2) - pb.min(2), pb.max(2) - pa.min(2))
    return np.all(~valid | (depth > eps), axis=1)


def find_penetrations(cp: CreasePattern, tolerance: float = 1e-6) -> np.ndarray:
    """Pairs of face indices (P, 2) of the folded model that intersect; ``tolerance`` is relative."""
    faces = np.flatnonzero(~cp.tab_faces) if len(cp.tab_faces) else np.arange(len(cp.faces))
    if len(faces) < 2:
        return np.zeros((0, 2), np.int64)
    v = cp.vertices_3d
    axes = np.ascontiguousarray(v.T)  # x, y, z rows: numpy reduces and gathers them faster than (N, 3)
    scale = float((axes.max(axis=1) - axes.min(axis=1)).max()) or 1.0
    eps = tolerance * scale
    face_w = _weld(v, eps)[cp.faces]
    # Broad phase on whole faces (half as many boxes as triangles), then adjacency.
    corners = [axis[cp.faces[faces]] for axis in axes]  # (F, 4) per axis
    lo = np.column_stack([np.minimum(np.minimum(c[:, 0], c[:, 1]), np.minimum(c[:, 2], c[:, 3])) for c in corners])
    hi = np.column_stack([np.maximum(np.maximum(c[:, 0], c[:, 1]), np.maximum(c[:, 2], c[:, 3])) for c in corners])
    del corners
    pairs = candidate_pairs(lo, hi)
    a, b = pairs[:, 0], pairs[:, 1]
    boxes = np.ones(len(pairs), dtype=bool)
    for low, high in zip(lo.T, hi.T):
        low, high = np.ascontiguousarray(low), np.ascontiguousarray(high)
        boxes &= (np.minimum(high[a], high[b]) - np.maximum(low[a], low[b])) > -eps
    fa, fb = faces[a[boxes]], faces[b[boxes]]
    del pairs, a, b, boxes
    adjacent = np.zeros(len(fa), dtype=bool)
    corner_ids = np.ascontiguousarray(face_w.T)
    ends_a, ends_b = [ids[fa] for ids in corner_ids], [ids[fb] for ids in corner_ids]
    for end in ends_a:
        for other in ends_b:
            adjacent |= end == other
    del ends_a, ends_b, corner_ids
    fa, fb = fa[~adjacent], fb[~adjacent]
    # Narrow phase on the faces' triangles (0, 1, 2) and (0, 2, 3), as in CreasePattern.triangles;
    # a triangular face repeats a vertex, and its degenerate half is left out.
    halves = np.stack([cp.faces[:, [0, 1, 2]], cp.faces[:, [0, 2, 3]]], axis=1)
    solid = ((halves[..., 0] != halves[..., 1]) & (halves[..., 1] != halves[..., 2])
             & (halves[..., 0] != halves[..., 2]))
    pa, pb = np.repeat(fa, 4), np.repeat(fb, 4)
    ta, tb = np.tile([0, 0, 1, 1], len(fa)), np.tile([0, 1, 0, 1], len(fa))
    ok = solid[pa, ta] & solid[pb, tb]
    pa, pb, ta, tb = pa[ok], pb[ok], ta[ok], tb[ok]
    hits = []
    for start in range(0, len(pa), 100_000):
        part = slice(start, start + 100_000)
        hit = _triangles_intersect(v[halves[pa[part], ta[part]]], v[halves[pb[part], tb[part]]], eps)
        hits.append(np.column_stack([pa[part][hit], pb[part][hit]]))
    found = _unique_pairs(np.concatenate(hits), len(cp.faces)) if hits else np.zeros((0, 2), np.int64)
    # Welding on a grid can split two vertices closer than eps across a cell boundary:
    # faces with any vertices that close touch there, so they are adjacent after all.
    gap = np.linalg.norm(v[cp.faces[found[:, 0]]][:, :, None] - v[cp.faces[found[:, 1]]][:, None, :], axis=-1)
    return found[gap.min(axis=(1, 2)) > eps]
