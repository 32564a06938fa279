"""Trajectory templates (CONVENTIONS.md): closed, counter-clockwise, starting mid-side.

Both templates start and end at the midpoint of the side from the last corner to
corner 0, so the start is not a corner and the seam is the plane perpendicular
to the first segment there.
"""

from __future__ import annotations

import numpy as np


def _closed_from_corners(corners: np.ndarray) -> np.ndarray:
    """The polyline midpoint(last, 0), corner 0 .. corner n-1, midpoint(last, 0), in 3D (z = 0)."""
    mid = 0.5 * (corners[-1] + corners[0])
    points = np.vstack([mid, corners, mid])
    return np.column_stack([points, np.zeros(len(points))])


def regular(corners: int, radius: float) -> np.ndarray:
    """Regular n-gon of circumradius ``radius``: corners at R(cos 2πk/n, sin 2πk/n)."""
    angles = 2.0 * np.pi * np.arange(corners) / corners
    return _closed_from_corners(radius * np.column_stack([np.cos(angles), np.sin(angles)]))


def star(points: int, outer_radius: float, inner_radius: float) -> np.ndarray:
    """Star with 2n corners at angles πi/n, outer radius for even i, inner for odd i."""
    i = np.arange(2 * points)
    angles = np.pi * i / points
    radii = np.where(i % 2 == 0, outer_radius, inner_radius)
    return _closed_from_corners(radii[:, None] * np.column_stack([np.cos(angles), np.sin(angles)]))
