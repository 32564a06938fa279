"""FOLD 1.1: the crease pattern as the top-level frame, the folded form as frame 1.

ORIPA rejects a top-level folded form and Origami Simulator reads only the
top-level frame, so the sheet comes first and the 3D state is
``file_frames[0]`` inheriting edges and faces on the same vertex indices.
"""

from __future__ import annotations

import json

import numpy as np

from foldfab import __version__
from foldfab.geometry.crease_pattern import CreasePattern


def to_fold(cp: CreasePattern, title: str = "") -> dict:
    """The FOLD dictionary of ``cp``."""
    return _plain(_fields(cp, title))


def dumps(cp: CreasePattern, title: str = "") -> str:
    """FOLD text of ``cp``: ``json.dumps(to_fold(cp, title), separators=(",", ":"))`` and a newline,
    byte for byte, with the large arrays written from numpy (:func:`_array_text`) rather than
    through a Python list per vertex, edge and face."""
    return _encode(_fields(cp, title)) + "\n"


class _Rows:
    """An array a FOLD list is written from: its rows (``keep``: the entries of each row to write)."""

    def __init__(self, values: np.ndarray, keep: np.ndarray | None = None):
        self.values, self.keep = values, keep


def _fields(cp: CreasePattern, title: str) -> dict:
    """The FOLD dictionary with its large lists as :class:`_Rows`."""
    return {
        "file_spec": 1.1,
        "file_creator": f"foldfab {__version__}",
        "file_title": title,
        "file_classes": ["singleModel"],
        "frame_title": "crease pattern",
        "frame_classes": ["creasePattern"],
        "frame_attributes": ["2D"],
        "frame_unit": "mm",
        "vertices_coords": _Rows(cp.vertices.round(9)),
        "edges_vertices": _Rows(cp.edges),
        "edges_assignment": cp.assignment.tolist(),
        # FOLD: "zero for flat, unassigned, and border folds" (F creases bend less than flat_angle).
        "edges_foldAngle": _Rows(np.where(np.isin(cp.assignment, ("M", "V")), cp.fold_angle, 0.0).round(9)),
        # faces as vertex lists without repeated ids (triangles have three), as cp.face_polygons()
        "faces_vertices": _Rows(cp.faces, cp.faces != np.roll(cp.faces, 1, axis=1)),
        "file_frames": [{
            "frame_title": "folded form",
            "frame_classes": ["foldedForm"],
            "frame_attributes": ["3D"],
            "frame_inherit": True,
            "frame_parent": 0,
            "frame_unit": "mm",
            "vertices_coords": _Rows(cp.vertices_3d.round(9)),
        }],
    }


def _plain(value):
    """``value`` with every :class:`_Rows` as nested lists."""
    if isinstance(value, dict):
        return {key: _plain(item) for key, item in value.items()}
    if isinstance(value, list):
        return [_plain(item) for item in value]
    if isinstance(value, _Rows):
        if value.keep is None:
            return value.values.tolist()
        return [[v for v, k in zip(row, keep) if k] for row, keep in zip(value.values.tolist(), value.keep.tolist())]
    return value


def _encode(value) -> str:
    """Compact JSON of ``value`` (as ``json.dumps`` with separators ``,`` and ``:``)."""
    if isinstance(value, dict):
        return "{" + ",".join(json.dumps(key) + ":" + _encode(item) for key, item in value.items()) + "}"
    if isinstance(value, list) and value and isinstance(value[0], (dict, list, _Rows)):  # (FOLD's lists are of one kind)
        return "[" + ",".join(_encode(item) for item in value) + "]"
    if isinstance(value, _Rows):
        return _array_text(value)
    return json.dumps(value, separators=(",", ":"))


def _array_text(rows: _Rows) -> str:
    """JSON of a 1D or 2D array as ``json.dumps`` writes its ``tolist()`` (floats as ``repr``,
    the text of each distinct value made once), the rows cut to their ``keep`` entries."""
    values = rows.values
    if values.dtype.kind == "f" and not np.all(np.isfinite(values)):
        return json.dumps(_plain(rows), separators=(",", ":"))  # NaN, Infinity: json's own spelling
    if values.ndim == 1:
        values, keep = values[:, None], None
    else:
        keep = rows.keep
    flat = values.ravel() if keep is None else values[keep]
    floats = values.dtype.kind == "f"
    # distinct by bit pattern for floats: 0.0 and -0.0 are equal, but json writes them apart
    keys = np.ascontiguousarray(flat, dtype=np.float64).view(np.int64) if floats else flat
    distinct, inverse = np.unique(keys, return_inverse=True)
    distinct = distinct.view(np.float64) if floats else distinct
    texts = np.array(list(map(repr if floats else str, distinct.tolist())) or [""], dtype=object)
    counts = np.full(len(values), values.shape[1]) if keep is None else keep.sum(axis=1)
    shapes = ["[" + ",".join(["%s"] * n) + "]" for n in range(values.shape[1] + 1)]
    if rows.values.ndim == 1:
        shapes = ["", "%s"]
    template = ",".join(np.asarray(shapes, dtype=object)[counts].tolist())
    return "[" + template % tuple(texts[inverse.ravel()].tolist()) + "]"
