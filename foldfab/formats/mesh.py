"""The folded 3D model as a triangle mesh (trimesh), for STL, OBJ, PLY and glTF files."""

from __future__ import annotations

import numpy as np

from foldfab.geometry.crease_pattern import CreasePattern


GLTF_FROM_FOLDFAB = np.array([[0.001, 0.0, 0.0, 0.0],
                              [0.0, 0.0, 0.001, 0.0],
                              [0.0, -0.001, 0.0, 0.0],
                              [0.0, 0.0, 0.0, 1.0]])
"""foldfab's z-up millimetres to glTF's y-up metres (glTF 2.0 §3.4): a quarter turn about x,
(x, y, z) mm -> (x, z, -y) / 1000 m, a rotation, so faces keep their winding.  Only GLB
needs it; STL, OBJ and PLY keep millimetres, z up."""


def to_trimesh(cp: CreasePattern, weld: bool = True):
    """The folded state as a ``trimesh.Trimesh``; ``weld`` joins coincident vertices (the seam).

    The glue tab is left out: folded, it lies flat under the first panel, and the two
    layers would share edges three ways (a mesh that is no surface to a renderer or a
    slicer).  The FOLD file keeps it.
    """
    import trimesh

    tris, owner = cp.triangles()
    tris = tris[~cp.tab_faces[owner]] if cp.tab_faces.any() else tris
    mesh = trimesh.Trimesh(vertices=cp.vertices_3d, faces=tris, process=False)
    if weld:
        mesh.merge_vertices()
    return mesh
