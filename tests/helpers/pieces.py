"""The check that a split design's pieces, glued back, are the whole crease pattern."""

from __future__ import annotations

import numpy as np


def _match(a: np.ndarray, b: np.ndarray, tol: float) -> np.ndarray:
    """(len(a), len(b)) bool: segments ``a`` (N, 2, 2) and ``b`` (M, 2, 2) with the same ends, either way round."""
    same = np.abs(a[:, None] - b[None]).max(axis=(2, 3)) <= tol
    flipped = np.abs(a[:, None] - b[None, :, ::-1]).max(axis=(2, 3)) <= tol
    return same | flipped


def _point_in_faces(points: np.ndarray, cp, tol: float) -> np.ndarray:
    """Whether each point lies on a face of ``cp`` (convex faces, ``tol`` mm of slack)."""
    inside = np.zeros(len(points), bool)
    for poly in cp.face_polygons():
        v = cp.vertices[poly]
        e = np.roll(v, -1, axis=0) - v
        rel = points[:, None] - v[None]
        cross = e[None, :, 0] * rel[..., 1] - e[None, :, 1] * rel[..., 0]
        lengths = np.maximum(np.linalg.norm(e, axis=1), 1e-300)
        inside |= np.all(cross / lengths >= -tol, axis=1)
    return inside


def assert_pieces_rebuild(cp, pieces) -> None:
    """Every crease and face of ``cp`` is in exactly one piece (pieces mapped back by their
    offsets, within 1e-9 of the design's size), with the same assignment, fold angle and folded
    position; a piece holds nothing else but glue tabs and the cut lines (borders on creases);
    match marks lie on the paper."""
    size = float(np.ptp(cp.vertices, axis=0).max())
    tol = 1e-9 * size
    whole = cp.vertices[cp.edges]
    owners = np.zeros(len(cp.edges), int)
    cut_sides = np.zeros(len(cp.edges), int)
    face_owners = np.zeros(len(cp.faces), int)
    whole_faces = [cp.vertices[p] for p in cp.face_polygons()]
    for piece in pieces:
        pc = piece.crease_pattern
        back = pc.vertices + piece.offset
        m = _match(back[pc.edges], whole, tol)
        for i, row in enumerate(m):
            hits = np.flatnonzero(row)
            assert len(hits) <= 1
            faces = [f for f in pc.edges_faces[i] if f >= 0]
            if all(piece.cut_tabs[f] for f in faces):   # a split's tab lies where the neighbour's panel does
                continue
            assert len(hits), f"piece {piece.number}: edge {i} is neither the design's nor a tab's"
            w = hits[0]
            if pc.assignment[i] == cp.assignment[w] and abs(pc.fold_angle[i] - cp.fold_angle[w]) <= 1e-9:
                owners[w] += 1
            else:
                assert pc.assignment[i] == "B" and cp.assignment[w] != "B", \
                    f"piece {piece.number}: edge {i} is {pc.assignment[i]}, the design's is {cp.assignment[w]}"
                cut_sides[w] += 1
        for f, poly in enumerate(pc.face_polygons()):
            corners = back[poly]
            if piece.cut_tabs[f]:
                continue
            hits = [g for g, other in enumerate(whole_faces) if len(other) == len(corners)
                    and np.abs(other.mean(axis=0) - corners.mean(axis=0)).max() <= tol
                    and (np.linalg.norm(other[:, None] - corners[None], axis=2).min(axis=0) <= tol).all()]
            assert hits, f"piece {piece.number}: face {f} is neither the design's nor a tab"
            g = hits[0]
            assert pc.tab_faces[f] == cp.tab_faces[g]
            face_owners[g] += 1
            np.testing.assert_allclose(pc.vertices_3d[poly].mean(axis=0),
                                       cp.vertices_3d[cp.face_polygons()[g]].mean(axis=0), atol=tol)
        if piece.marks:
            points = np.concatenate(piece.marks)
            assert _point_in_faces(points, pc, 1e-6 * size).all(), f"piece {piece.number}: a match mark is off the paper"
    # Every edge is in exactly one piece as it is in the design (a cut crease: as the fold of the
    # tab's piece); the other piece beside a cut has it as a cut line, a border.
    assert (owners == 1).all(), f"{int((owners != 1).sum())} edges of the design are not in exactly one piece"
    assert (cut_sides <= 1).all()
    assert (face_owners == 1).all(), "a face of the design is not in exactly one piece"

