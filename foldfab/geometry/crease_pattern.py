"""The crease pattern and its folded state, built from a :class:`Reflection` grid.

Crease-pattern coordinates (CONVENTIONS.md): ``x`` is the distance travelled
along the line element, ``y`` the arc length along the profile.  Vertex
``(j, k)`` is line element ``j`` crossing plane ``k``; zero-length segments
merge their two end vertices (the diamond pattern), so a face is a trapezoid or
a triangle.  Every crease gets its fold angle from the signed dihedral angle of
the 3D model, seen from the front of the crease pattern: valley positive, as in
FOLD.  Pure geometry: no I/O.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from foldfab.errors import DesignError
from foldfab.geometry.reflection import Reflection

BORDER, MOUNTAIN, VALLEY, FLAT = "B", "M", "V", "F"
FLAT_FOLD_TOL = 1e-6  # degrees: a fold closer than this to 180 has no defined direction
CHAMFER = 0.45
"""The most of the outer edge of a glue tab's end face that the tab's chamfer takes away (the
outer edge keeps the rest, so even a one-face tab stays a quadrilateral)."""


@dataclass(frozen=True)
class CreasePattern:
    """Vertices (2D sheet and 3D folded), quad faces, and edges with assignments.

    ``faces`` is (F, 4) counter-clockwise in the sheet; a triangle repeats one
    vertex id.  ``face_grid[f] = (j, k)``: the face lies between line elements
    ``j`` and ``j+1`` and planes ``k`` and ``k+1`` (``k = K`` is the glue tab).
    ``edges_faces`` holds the two faces beside each edge (-1 for none).
    """

    vertices: np.ndarray          # (V, 2) mm
    vertices_3d: np.ndarray       # (V, 3) mm, folded state
    faces: np.ndarray             # (F, 4) int
    face_grid: np.ndarray         # (F, 2) int (j, k)
    edges: np.ndarray             # (E, 2) int
    assignment: np.ndarray        # (E,) '<U1' in B, M, V, F
    fold_angle: np.ndarray        # (E,) degrees, valley positive, 0 on borders
    edges_faces: np.ndarray       # (E, 2) int
    tab_faces: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))  # (F,) glue-tab faces

    @property
    def edge_lengths(self) -> np.ndarray:
        """Length of every edge on the sheet, mm."""
        return np.linalg.norm(np.diff(self.vertices[self.edges], axis=1)[:, 0], axis=1)

    @property
    def sheet_size(self) -> tuple[float, float]:
        """Width and height of the sheet's bounding box, mm."""
        span = np.ptp(self.vertices, axis=0)
        return float(span[0]), float(span[1])

    def face_polygons(self) -> list[list[int]]:
        """Faces as vertex lists without repeated ids (triangles have three)."""
        out = []
        for face in self.faces.tolist():
            poly = [v for i, v in enumerate(face) if v != face[i - 1]]
            out.append(poly)
        return out

    def triangles(self) -> tuple[np.ndarray, np.ndarray]:
        """Triangulation of the faces: (T, 3) vertex ids and (T,) face index, degenerate ones dropped."""
        f = self.faces
        tris = np.concatenate([f[:, [0, 1, 2]], f[:, [0, 2, 3]]])
        owner = np.concatenate([np.arange(len(f)), np.arange(len(f))])
        ok = (tris[:, 0] != tris[:, 1]) & (tris[:, 1] != tris[:, 2]) & (tris[:, 0] != tris[:, 2])
        return tris[ok], owner[ok]


def face_normals(points: np.ndarray) -> np.ndarray:
    """Unit normals of the (J-1, C-1) grid quads, from the cross product of their diagonals."""
    a = points[:-1, :-1]
    b = points[:-1, 1:]
    c = points[1:, 1:]
    d = points[1:, :-1]
    n = np.cross(c - a, d - b)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def _fold_angles(n1: np.ndarray, n2: np.ndarray, edge_dir: np.ndarray) -> np.ndarray:
    """Signed dihedral angles (degrees): ``n1`` is the face left of ``edge_dir`` in the sheet."""
    e = edge_dir / np.linalg.norm(edge_dir, axis=-1, keepdims=True)
    sin = np.einsum("...i,...i->...", np.cross(n2, n1), e)
    cos = np.einsum("...i,...i->...", n1, n2)
    return np.degrees(np.arctan2(sin, cos))


def tab_edge(cut: np.ndarray, edge: np.ndarray, near_3d: np.ndarray, edge_3d: np.ndarray, width: float,
             axis: int, tolerance: float, what: Callable[[int], str]) -> tuple[np.ndarray, np.ndarray]:
    """The far edge of a glue tab ``width`` mm wide: the tab is the strip of the neighbouring panel
    next to the cut, copied onto the cut's other side, so that it lies under that panel when folded.

    ``cut`` (N, 2) are the cut's vertices on the sheet, ``edge`` (N, 2) the neighbouring panel's
    edges that leave the cut across the panel (``near_3d``, ``edge_3d``: where they start and
    run in the folded model), ``axis`` the sheet axis the width is measured along (0: x, for a
    cut along a mirror crease; 1: y, along a line element).  The tab must not reach past the
    panel's narrowest width: an edge shorter than ``width`` across is an error naming it
    (``what(i)``).  The tab's two ends are chamfered (:func:`_chamfer`).  Returns the tab's far
    vertices on the sheet (N, 2) and folded (N, 3)."""
    across = np.abs(edge[:, axis])
    if np.any(across < width - tolerance):
        i = int(np.argmin(across))
        raise DesignError(f"[crease].glue_tab: {width:g} mm is longer than {what(i)} ({across[i]:.4g} mm), "
                          f"which the tab must lie on; reduce glue_tab to at most {across.min():.4g}")
    t = (width / np.maximum(across, tolerance))[:, None]
    return _chamfer(cut, cut + t * edge, near_3d + t * edge_3d, width, 1 - axis)


def _chamfer(cut: np.ndarray, far: np.ndarray, far_3d: np.ndarray, width: float,
             along: int) -> tuple[np.ndarray, np.ndarray]:
    """A tab's far vertices with both ends chamfered: each end's outer corner moves along its
    end face's outer edge until it lies ``width`` further in along the cut (sheet axis
    ``along``) than the cut's end, so that a square end leans in at 45 degrees; at most
    :data:`CHAMFER` of that edge.  The folded corner moves by the same fraction of the same
    edge, so the chamfered tab is a part of the square one: it still lies under the
    neighbouring panel, never past its narrowest width, and its faces stay the same faces."""
    out, out_3d = far.copy(), far_3d.copy()
    inward = np.sign(cut[-1, along] - cut[0, along])
    for end, inner, sign in ((0, 1, inward), (-1, -2, -inward)):
        run = far[inner, along] - far[end, along]
        if sign * run <= 0:   # an outer edge that does not run inward: no chamfer
            continue
        f = min(max((cut[end, along] + sign * width - far[end, along]) / run, 0.0), CHAMFER)
        out[end] = far[end] + f * (far[inner] - far[end])
        out_3d[end] = far_3d[end] + f * (far_3d[inner] - far_3d[end])
    return out, out_3d


def tabbed_grid(grid: Reflection, glue_tab: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """The grid's crossings ``x`` (J, C), their sheet heights ``y`` (J, C: the profile's arc
    length, but where a tab's chamfer moves a corner) and 3D ``points`` (J, C, 3), with a closed
    design's seam tab (``glue_tab`` > 0) as one more column lying on the first panel; and that
    column count (0 or 1)."""
    x, points = grid.x, grid.points
    heights = np.broadcast_to(grid.arc[:, None], x.shape)
    if glue_tab <= 0:
        return x, heights, points, 0
    if not grid.closed:
        raise DesignError("[crease].glue_tab: a glue tab joins the two ends of a closed trajectory; "
                          "this trajectory is open: set glue_tab = 0")
    cut = np.column_stack([x[:, -1], grid.arc])
    edge = np.column_stack([x[:, 1] - x[:, 0], np.zeros(len(x))])
    far, far_3d = tab_edge(cut, edge, points[:, 0], points[:, 1] - points[:, 0], glue_tab, 0, grid.tolerance,
                           lambda j: f"the first segment of line element {j}")
    return (np.column_stack([x, far[:, 0]]), np.column_stack([heights, far[:, 1]]),
            np.concatenate([points, far_3d[:, None]], axis=1), 1)


def build_crease_pattern(grid: Reflection, flat_angle: float = 1.0, glue_tab: float = 0.0) -> CreasePattern:
    """Crease pattern of ``grid``; creases folding less than ``flat_angle`` degrees are flat."""
    x, y, points, tab_columns = tabbed_grid(grid, glue_tab)
    J, C = x.shape
    grid_ids = np.stack(np.meshgrid(np.arange(J - 1), np.arange(C - 1), indexing="ij"), axis=-1)
    tab = grid_ids[..., 1] >= C - 1 - tab_columns
    return grid_pattern(x, y, points, flat_angle, grid_ids, tab)


def grid_pattern(x: np.ndarray, y: np.ndarray, points: np.ndarray, flat_angle: float, grid_ids: np.ndarray,
                 tab: np.ndarray, keep: np.ndarray | None = None, normals: np.ndarray | None = None) -> CreasePattern:
    """The crease pattern of a grid of crossings: ``x`` (J, C) on the sheet at heights ``y`` (J,
    or (J, C) where a tab's chamfer moves a corner off its line element), ``points`` (J, C, 3) folded.  Its (J-1, C-1) cells are faces: ``grid_ids`` names each by the
    design's (profile segment, trajectory segment), ``tab`` marks glue tabs, ``keep`` the cells
    that are faces at all (default every one), ``normals`` their folded normals (default from
    ``points``; a piece passes the whole design's, so that its folds are the design's exactly)."""
    J, C = x.shape
    heights = np.broadcast_to(y[:, None], (J, C)) if y.ndim == 1 else y
    seglen = np.diff(x, axis=1)
    zero = (seglen == 0.0) & (np.diff(heights, axis=1) == 0.0)
    both = zero[:-1] & zero[1:]
    if np.any(both):
        j, k = map(int, grid_ids[tuple(np.argwhere(both)[0])])
        raise DesignError(f"profile segment {j}-{j + 1} collapses to a line on trajectory segment {k} "
                          "(both its line elements have zero length there); move [profile].offset by a small amount")

    new = np.ones((J, C), bool)
    new[:, 1:] = ~zero
    ids = np.cumsum(new.ravel()).reshape(J, C) - 1
    vertices = np.column_stack([x[new], heights[new]])
    vertices_3d = points[new]

    faces = np.stack([ids[:-1, :-1], ids[:-1, 1:], ids[1:, 1:], ids[1:, :-1]], axis=-1).reshape(-1, 4)
    face_grid = grid_ids.reshape(-1, 2)
    kept = np.ones(len(faces), bool) if keep is None else keep.ravel()
    face_id = np.where(kept, np.cumsum(kept) - 1, -1).reshape(J - 1, C - 1)
    normals = (face_normals(points) if normals is None else normals).reshape(-1, 3)[kept]

    # Horizontal edges (along line elements), pointing +x: face (j, k) lies left (above), (j-1, k) right.
    hj, hk = np.nonzero(~zero)
    h_edges = np.column_stack([ids[hj, hk], ids[hj, hk + 1]])
    h_left = np.where(hj < J - 1, face_id[np.minimum(hj, J - 2), hk], -1)
    h_right = np.where(hj > 0, face_id[np.maximum(hj - 1, 0), hk], -1)
    h_dir = points[hj, hk + 1] - points[hj, hk]
    # Skew edges (along mirror planes), pointing +y: face (j, k-1) lies left, (j, k) right.
    sj, sk = np.meshgrid(np.arange(J - 1), np.arange(C), indexing="ij")
    sj, sk = sj.ravel(), sk.ravel()
    s_edges = np.column_stack([ids[sj, sk], ids[sj + 1, sk]])
    s_left = np.where(sk > 0, face_id[sj, np.maximum(sk - 1, 0)], -1)
    s_right = np.where(sk < C - 1, face_id[sj, np.minimum(sk, C - 2)], -1)
    s_dir = points[sj + 1, sk] - points[sj, sk]

    edges = np.concatenate([h_edges, s_edges])
    left = np.concatenate([h_left, s_left])
    right = np.concatenate([h_right, s_right])
    direction = np.concatenate([h_dir, s_dir])
    del h_edges, s_edges, h_left, s_left, h_right, s_right, h_dir, s_dir, hj, hk, sj, sk
    present = (left >= 0) | (right >= 0)
    if not present.all():
        edges, left, right, direction = edges[present], left[present], right[present], direction[present]
    faces, face_grid = faces[kept], face_grid[kept]
    border = (left < 0) | (right < 0)
    angle = np.zeros(len(edges))
    inner = ~border
    rows = np.flatnonzero(inner)
    for part in range(0, len(rows), 1 << 20):   # in slices: a million faces' temporaries are (E, 3) each
        e = rows[part:part + (1 << 20)]
        angle[e] = _fold_angles(normals[left[e]], normals[right[e]], direction[e])
    del direction
    flat_fold = inner & (np.abs(angle) > 180.0 - FLAT_FOLD_TOL)
    if np.any(flat_fold):
        e = int(np.argmax(flat_fold))
        j, k = face_grid[right[e]]
        raise DesignError(f"the paper folds flat onto itself (180 degrees) between profile segment {j} and trajectory "
                          f"segment {k}: the folded model cannot tell mountain from valley there; tilt the profile or "
                          "the trajectory so no mirror is perpendicular to the paper")
    assignment = np.full(len(edges), FLAT, dtype="<U1")
    folded = inner & (np.abs(angle) >= flat_angle) & (angle != 0.0)
    assignment[folded & (angle > 0)] = VALLEY
    assignment[folded & (angle < 0)] = MOUNTAIN
    assignment[border] = BORDER
    if keep is not None:   # drop the vertices of cells that are no faces
        used = np.zeros(len(vertices), bool)
        used[faces.ravel()] = True
        renumber = np.cumsum(used) - 1
        vertices, vertices_3d, faces, edges = vertices[used], vertices_3d[used], renumber[faces], renumber[edges]
    return CreasePattern(vertices, vertices_3d, faces, face_grid, edges, assignment, angle,
                         np.column_stack([left, right]), tab.ravel()[kept])
