"""Penetration check: agrees with a brute-force reference, finds real crossings, spares touching faces."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from foldfab.geometry import templates
from foldfab.geometry.crease_pattern import build_crease_pattern
from foldfab.errors import DesignError
from foldfab.job import parse_job
from foldfab.design import build_design
from foldfab.formats.mesh import to_trimesh
from foldfab.geometry.penetration import candidate_pairs, find_penetrations
from foldfab.geometry.reflection import reflect


def _segment_crosses(p, q, tri, margin, depth=0.0):
    """Segment p-q crosses the interior of triangle ``tri`` (Moller-Trumbore).

    ``margin``: how far inside the triangle (barycentric) and the segment the crossing must be;
    ``depth``: how far (mm) both ends must lie from the triangle's plane, so paper lying flat
    on paper (folded back within a hair) counts as touching, not crossing.
    """
    a, b, c = tri
    e1, e2 = b - a, c - a
    n = np.cross(e1, e2)
    n = n / np.linalg.norm(n)
    if min(abs(np.dot(p - a, n)), abs(np.dot(q - a, n))) < depth:
        return False
    d = q - p
    h = np.cross(d, e2)
    det = np.dot(e1, h)
    if abs(det) < 1e-12:
        return False
    s = p - a
    u = np.dot(s, h) / det
    qv = np.cross(s, e1)
    v = np.dot(d, qv) / det
    t = np.dot(e2, qv) / det
    return u > margin and v > margin and u + v < 1 - margin and margin < t < 1 - margin


def _straddles(tri, other, depth):
    """``other`` reaches at least ``depth`` mm to both sides of ``tri``'s plane."""
    n = np.cross(tri[1] - tri[0], tri[2] - tri[0])
    side = (other - tri[0]) @ (n / np.linalg.norm(n))
    return side.max() >= depth and side.min() <= -depth


def brute_force(cp, margin, depth=0.0):
    """Face pairs with no vertices within the library's tolerance whose triangles cross.

    A crossing is an edge through the other triangle's interior (barycentric ``margin``);
    with ``depth`` > 0 each triangle must also reach ``depth`` mm to both sides of the
    other's plane, so a hair's poke-through counts as touching.
    """
    tris, owner = cp.triangles()
    v = cp.vertices_3d
    eps = 1e-6 * float(np.ptp(v, axis=0).max())
    found = set()
    for i in range(len(tris)):
        for j in range(i + 1, len(tris)):
            fa, fb = int(owner[i]), int(owner[j])
            if fa == fb or cp.tab_faces[fa] or cp.tab_faces[fb]:
                continue
            gap = np.linalg.norm(v[cp.faces[fa]][:, None] - v[cp.faces[fb]][None, :], axis=-1).min()
            if gap <= eps:
                continue
            A, B = v[tris[i]], v[tris[j]]
            if depth and not (_straddles(A, B, depth) and _straddles(B, A, depth)):
                continue
            if any(_segment_crosses(A[k], A[(k + 1) % 3], B, margin, depth) for k in range(3)) or \
               any(_segment_crosses(B[k], B[(k + 1) % 3], A, margin, depth) for k in range(3)):
                found.add((min(fa, fb), max(fa, fb)))
    return found


def test_self_crossing_profile_penetrates():
    profile = np.array([[0, 0], [6, 10], [6, 0], [0, 10]], float)
    cp = build_crease_pattern(reflect(profile, templates.regular(6, 40)))
    pairs = find_penetrations(cp)
    assert len(pairs) > 0
    assert {tuple(p) for p in pairs.tolist()} == brute_force(cp, 1e-9)


def test_touching_faces_are_not_penetration():
    """The diamond pattern: many faces meet at merged vertices, none cross."""
    w = 40 * math.sin(math.pi / 8) * math.tan(math.pi / 8)
    profile = np.array([[w, 0], [-w, 12], [w, 24], [-w, 36]], float)
    cp = build_crease_pattern(reflect(profile, templates.regular(8, 40)))
    assert len(find_penetrations(cp)) == 0


@settings(max_examples=25, deadline=None)
@example(n=4, us=[0.0, 1.0, 2.0, 0.0, 0.0], vs=[0.0, 0.0, 1e-05, 0.0, 1.0, 0.0])  # folded flat onto itself
@given(n=st.sampled_from([4, 6, 8]), us=st.lists(st.floats(-8, 8), min_size=3, max_size=6),
       vs=st.lists(st.floats(-15, 15), min_size=6, max_size=6))
def test_agrees_with_brute_force(n, us, vs):
    """Random (often self-crossing) profiles: no missed crossing, no invented one."""
    profile = np.column_stack([us, vs[:len(us)]])
    assume(np.all(np.linalg.norm(np.diff(profile, axis=0), axis=1) > 0.5))
    try:
        cp = build_crease_pattern(reflect(profile, templates.regular(n, 40)))
    except DesignError:
        assume(False)
    found = {tuple(p) for p in find_penetrations(cp).tolist()}
    assert brute_force(cp, 1e-3, 1e-3) <= found    # every clear crossing is found
    assert found <= brute_force(cp, -1e-6)          # nothing found that does not (nearly) cross


def _job(profile: str, extra: str = "") -> str:
    return f"""
[profile]
points = {profile}
[trajectory]
template = "regular"
corners = 6
radius = 40
{extra}
"""


def test_penetration_is_an_error_unless_allowed(tmp_path):
    job = parse_job(_job("[[0, 0], [6, 10], [6, 0], [0, 10]]"), tmp_path / "x.toml")
    with pytest.raises(DesignError, match=r"penetration: \d+ pair\(s\) of faces .* face \d+ \(profile segment"):
        build_design(job)
    design = build_design(job, allow_penetration=True)
    assert len(design.penetrations) > 0 and design.warnings and "--allow" not in design.warnings[0]


def test_mesh_is_welded_at_the_seam():
    profile = np.array([[0, 0], [4, 10], [0, 20]], float)
    cp = build_crease_pattern(reflect(profile, templates.regular(6, 40)))
    mesh = to_trimesh(cp)
    # a closed column is a tube: welded, its only open edges are the top and bottom rims
    assert len(mesh.vertices) == len(cp.vertices) - 3
    assert mesh.is_winding_consistent


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.tuples(st.integers(0, 40), st.integers(0, 40), st.integers(0, 40)),
                          st.tuples(st.integers(0, 6), st.integers(0, 6), st.integers(0, 6))), min_size=2, max_size=30),
       st.sampled_from([1.0, 1e6]))
def test_candidate_pairs_hold_every_overlapping_pair_once(boxes, spread):
    """Boxes on a lattice (touching and equal ones common), close together or spread so far
    apart that a cell and a box no longer fit one 64-bit number: every two that overlap or
    touch are among the pairs, each pair once, smaller box first."""
    corner = np.array([b[0] for b in boxes], dtype=float) * spread
    lo, hi = corner, corner + np.array([b[1] for b in boxes], dtype=float)
    pairs = candidate_pairs(lo, hi).tolist()
    assert all(i < j for i, j in pairs) and len(set(map(tuple, pairs))) == len(pairs)
    touching = {(i, j) for i in range(len(boxes)) for j in range(i + 1, len(boxes))
                if np.all(np.minimum(hi[i], hi[j]) >= np.maximum(lo[i], lo[j]))}
    assert touching <= set(map(tuple, pairs))


def test_boxes_that_are_one_point_far_from_the_origin_pair_without_overflow():
    """All boxes one point: the grid's cell is its floor (1e-12), and a coordinate of 40 km over it
    is past 64 bits unless cells are counted from the lowest corner."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        pairs = candidate_pairs(np.full((3, 3), 4e7), np.full((3, 3), 4e7))
    assert sorted(map(tuple, pairs.tolist())) == [(0, 1), (0, 2), (1, 2)]
