"""Geometric invariants every design must satisfy, checked independently of the construction."""

from __future__ import annotations

import numpy as np

from foldfab.geometry.crease_pattern import CreasePattern
from foldfab.geometry.reflection import Reflection

PAIRS = [(0, 1), (1, 2), (2, 3), (3, 0), (0, 2), (1, 3)]


def assert_isometric(cp: CreasePattern, rel: float = 1e-9) -> None:
    """Every face: its four sides and two diagonals have equal length on the sheet and in 3D."""
    f = cp.faces
    scale = max(float(np.ptp(cp.vertices, axis=0).max()), 1.0)
    for a, b in PAIRS:
        d2 = np.linalg.norm(cp.vertices[f[:, a]] - cp.vertices[f[:, b]], axis=1)
        d3 = np.linalg.norm(cp.vertices_3d[f[:, a]] - cp.vertices_3d[f[:, b]], axis=1)
        assert np.all(np.abs(d2 - d3) <= rel * scale), f"non-isometric face side {a}-{b}: {np.abs(d2 - d3).max()}"


def assert_planar_faces(cp: CreasePattern, rel: float = 1e-9) -> None:
    """The four corners of every 3D face lie in one plane."""
    p = cp.vertices_3d[cp.faces]
    scale = max(float(np.ptp(cp.vertices_3d, axis=0).max()), 1.0)
    vol = np.einsum("ij,ij->i", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]))
    assert np.all(np.abs(vol) <= rel * scale ** 3), f"non-planar face: {np.abs(vol).max()}"


def assert_ccw_trapezoids(cp: CreasePattern) -> None:
    """Faces are counter-clockwise on the sheet with two horizontal sides, but for a glue tab's
    end faces, whose chamfer moves their outer corners off the line elements."""
    p = cp.vertices[cp.faces]
    x, y = p[..., 0], p[..., 1]
    area = 0.5 * np.sum(x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y, axis=1)
    assert np.all(area > 0)
    bottom, top = np.isclose(p[:, 0, 1], p[:, 1, 1]), np.isclose(p[:, 2, 1], p[:, 3, 1])
    tab = cp.tab_faces if len(cp.tab_faces) else np.zeros(len(p), bool)
    assert np.all((bottom & top) | tab)


def assert_fold_signs(cp: CreasePattern, flat_angle: float) -> None:
    """Assignment agrees with the fold angle, and the fold angle's sign with the 3D geometry.

    Independent of the dihedral formula: an edge is a valley when the far corner of the
    right-hand face lies on the front side of the left-hand face (the faces rise towards
    the viewer of the crease pattern's front).
    """
    a = cp.assignment
    angle = cp.fold_angle
    assert np.all(angle[a == "V"] >= flat_angle) and np.all(angle[a == "V"] > 0)
    assert np.all(angle[a == "M"] <= -flat_angle) and np.all(angle[a == "M"] < 0)
    assert np.all(np.abs(angle[a == "F"]) < max(flat_angle, 1e-12) + 1e-12)
    assert np.all(angle[a == "B"] == 0)
    creases = np.flatnonzero((a == "M") | (a == "V"))
    left, right = cp.edges_faces[creases, 0], cp.edges_faces[creases, 1]
    v3 = cp.vertices_3d
    fl = cp.faces[left]
    normal = np.cross(v3[fl[:, 2]] - v3[fl[:, 0]], v3[fl[:, 3]] - v3[fl[:, 1]])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    # the vertex of the right face farthest from the edge
    fr = cp.faces[right]
    e0, e1 = v3[cp.edges[creases, 0]], v3[cp.edges[creases, 1]]
    cand = v3[fr]  # (E, 4, 3)
    axis = (e1 - e0) / np.linalg.norm(e1 - e0, axis=1, keepdims=True)
    rel = cand - e0[:, None]
    dist = np.linalg.norm(rel - np.einsum("eij,ej->ei", rel, axis)[..., None] * axis[:, None], axis=2)
    far = cand[np.arange(len(creases)), np.argmax(dist, axis=1)]
    side = np.einsum("ij,ij->i", far - e0, normal)
    big = np.abs(angle[creases]) > 1e-6
    assert np.all(np.sign(side[big]) == np.sign(angle[creases][big])), "fold angle sign disagrees with geometry"


def assert_closes(grid: Reflection) -> None:
    """A closed design's line elements end in 3D where they started."""
    if grid.closed:
        scale = max(float(np.ptp(grid.points.reshape(-1, 3), axis=0).max()), 1.0)
        assert np.abs(grid.points[:, -1] - grid.points[:, 0]).max() <= 1e-9 * scale


def assert_design_invariants(grid: Reflection, cp: CreasePattern, flat_angle: float) -> None:
    """All of the above."""
    assert_isometric(cp)
    assert_planar_faces(cp)
    assert_ccw_trapezoids(cp)
    assert_fold_signs(cp, flat_angle)
    assert_closes(grid)
    assert np.all(grid.segment_lengths >= 0)
