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
    return {
        "file_spec": 1.1,
        "file_creator": f"foldfab {__version__}",
        "file_title": title,
        "file_classes": ["singleModel"],
        "frame_title": "crease pattern",
        "frame_classes": ["creasePattern"],
        "frame_attributes": ["2D"],
        "frame_unit": "mm",
        "vertices_coords": cp.vertices.round(9).tolist(),
        "edges_vertices": cp.edges.tolist(),
        "edges_assignment": cp.assignment.tolist(),
        # FOLD: "zero for flat, unassigned, and border folds" (F creases bend less than flat_angle).
        "edges_foldAngle": np.where(np.isin(cp.assignment, ("M", "V")), cp.fold_angle, 0.0).round(9).tolist(),
        "faces_vertices": cp.face_polygons(),
        "file_frames": [{
            "frame_title": "folded form",
            "frame_classes": ["foldedForm"],
            "frame_attributes": ["3D"],
            "frame_inherit": True,
            "frame_parent": 0,
            "frame_unit": "mm",
            "vertices_coords": cp.vertices_3d.round(9).tolist(),
        }],
    }


def dumps(cp: CreasePattern, title: str = "") -> str:
    """FOLD text of ``cp`` (JSON)."""
    return json.dumps(to_fold(cp, title), separators=(",", ":")) + "\n"
