"""Part-way folded states: every fold angle scaled by ``t`` (0 flat, 1 the folded model), and the strain.

A spanning tree of the faces (breadth first from the face nearest the middle of the sheet) places
each face by turning it about the crease it shares with its parent by ``t`` times that crease's
fold angle.  At ``t = 1`` this is the folded model exactly and at ``t = 0`` a flat sheet; between,
a column's creases generally cannot all turn by the same fraction at once (the paper would have to
stretch), so the faces reached along different paths of the tree disagree where they meet.  Each
vertex is placed at the mean of its faces' placements, and the *strain* of a face is the largest
change, against the crease pattern, of the length of its sides and diagonal, relative to its
longest one (so a sliver face does not read as torn): what Origami Simulator shows in colour as
the strain of its bars.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from foldfab.geometry.crease_pattern import CreasePattern


@dataclass(frozen=True)
class FoldState:
    """The vertices (V, 3) at fraction ``t``, and the strain per face (F,) and per vertex (V,)."""

    t: float
    vertices: np.ndarray
    face_strain: np.ndarray
    vertex_strain: np.ndarray


def _rotations(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations by ``angle`` (radians) about unit ``axis`` (N, 3), right-handed (Rodrigues)."""
    c, s = np.cos(angle)[:, None, None], np.sin(angle)[:, None, None]
    x, y, z = axis.T
    zero = np.zeros_like(x)
    cross = np.stack([np.stack([zero, -z, y], 1), np.stack([z, zero, -x], 1), np.stack([-y, x, zero], 1)], 1)
    return c * np.eye(3) + s * cross + (1 - c) * axis[:, :, None] * axis[:, None, :]


def _root_pose(flat: np.ndarray, folded: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rigid motion (R, t) taking the flat face points onto their folded places (Kabsch)."""
    a, b = flat - flat.mean(axis=0), folded - folded.mean(axis=0)
    u, _, vt = np.linalg.svd(a.T @ b)
    d = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    rotation = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return rotation, folded.mean(axis=0) - rotation @ flat.mean(axis=0)


def _tree(cp: CreasePattern, root: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Breadth-first levels of the face tree: (faces, their parents, the creases between)."""
    ef = cp.edges_faces
    inner = np.flatnonzero((ef >= 0).all(axis=1))
    source = np.concatenate([ef[inner, 0], ef[inner, 1]])
    target = np.concatenate([ef[inner, 1], ef[inner, 0]])
    via = np.concatenate([inner, inner])
    order = np.argsort(source, kind="stable")
    source, target, via = source[order], target[order], via[order]
    starts = np.searchsorted(source, np.arange(len(cp.faces) + 1))
    seen = np.zeros(len(cp.faces), bool)
    seen[root] = True
    frontier, levels = np.array([root]), []
    while len(frontier):
        counts = starts[frontier + 1] - starts[frontier]
        first = np.repeat(starts[frontier], counts)
        index = first + np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
        keep = ~seen[target[index]]
        faces, pick = np.unique(target[index][keep], return_index=True)
        parents, creases = source[index][keep][pick], via[index][keep][pick]
        seen[faces] = True
        if len(faces):
            levels.append((faces, parents, creases))
        frontier = faces
    return levels


def fold_state(cp: CreasePattern, t: float) -> FoldState:
    """``cp`` with every fold angle times ``t`` (0 to 1); faces not joined to the middle one stay flat."""
    t = float(np.clip(t, 0.0, 1.0))
    flat = np.column_stack([cp.vertices, np.zeros(len(cp.vertices))])
    centres = flat[cp.faces].mean(axis=1)
    root = int(np.argmin(np.linalg.norm(centres - flat.mean(axis=0), axis=1)))
    rotation = np.empty((len(cp.faces), 3, 3))
    shift = np.empty((len(cp.faces), 3))
    ids = np.unique(cp.faces[root])
    rotation[:], shift[:] = _root_pose(flat[ids], cp.vertices_3d[ids])
    for faces, parents, creases in _tree(cp, root):
        a, b = flat[cp.edges[creases, 0]], flat[cp.edges[creases, 1]]
        axis = (b - a) / np.linalg.norm(b - a, axis=1, keepdims=True)
        # A valley (positive angle) lifts the face right of the edge towards the front: -angle about
        # the edge's direction for that face, +angle for the face on its left.
        side = np.where(cp.edges_faces[creases, 1] == faces, -1.0, 1.0)
        turn = _rotations(axis, side * t * np.radians(cp.fold_angle[creases]))
        rotation[faces] = rotation[parents] @ turn
        shift[faces] = np.einsum("nij,nj->ni", rotation[parents], a - np.einsum("nij,nj->ni", turn, a)) + shift[parents]
    placed = np.einsum("fij,fkj->fki", rotation, flat[cp.faces]) + shift[:, None, :]   # (F, 4, 3)
    total = np.zeros_like(flat)
    count = np.zeros(len(flat))
    np.add.at(total, cp.faces.ravel(), placed.reshape(-1, 3))
    np.add.at(count, cp.faces.ravel(), 1.0)
    vertices = total / np.maximum(count, 1.0)[:, None]
    pairs = np.array([[0, 1], [1, 2], [2, 3], [3, 0], [0, 2]])
    a, b = cp.faces[:, pairs[:, 0]], cp.faces[:, pairs[:, 1]]
    sheet = np.linalg.norm(flat[a] - flat[b], axis=2)
    now = np.linalg.norm(vertices[a] - vertices[b], axis=2)
    size = sheet.max(axis=1)
    face_strain = np.where(size > 0, np.abs(now - sheet).max(axis=1) / np.where(size > 0, size, 1.0), 0.0)
    vertex_strain = np.zeros(len(flat))
    np.maximum.at(vertex_strain, cp.faces.ravel(), np.repeat(face_strain, 4))
    return FoldState(t, vertices, face_strain, vertex_strain)
