"""A drag knife as the blade-compensation tests model it: the tip the knife's axis drags.

Independent of :mod:`foldfab.fabrication.blade`: the tip is a point held at the blade offset
from the axis that moves only along the line joining them (a tractrix), so it runs behind a
straight move and stays put while the axis circles it.  Along a straight axis move of length
``s`` the angle ``psi`` between the blade and the move's backward direction follows
``tan(psi / 2) = tan(psi0 / 2) * exp(-s / offset)``.
"""

from __future__ import annotations

import math

import numpy as np


def dragged_tip(axis: np.ndarray, offset: float, samples: int = 4) -> np.ndarray:
    """The tip's path (complex) while the knife's axis follows polyline ``axis`` (complex or
    (N, 2)), the blade starting along the first move; ``samples`` tip points per move."""
    axis = as_complex(axis)
    moves = np.diff(axis)
    first = moves[np.abs(moves) > 0]
    if offset == 0 or not len(first):
        return axis
    tip = axis[0] - offset * first[0] / abs(first[0])
    out = [tip]
    for start, move in zip(axis[:-1], moves):
        length = abs(move)
        if length == 0:
            continue
        back = -move / length
        psi0 = float(np.angle((tip - start) / back))
        for s in np.linspace(0, length, samples + 1)[1:]:
            psi = 2 * math.atan(math.tan(psi0 / 2) * math.exp(-s / offset))
            out.append(start + move * s / length + offset * back * np.exp(1j * psi))
        tip = out[-1]
    return np.array(out)


def as_complex(points: np.ndarray) -> np.ndarray:
    """Points as a complex array (from (N, 2) or complex)."""
    points = np.asarray(points)
    return points if np.iscomplexobj(points) else points[:, 0] + 1j * points[:, 1]


def distance_to_polyline(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """The distance of each of ``points`` (complex) from polyline ``line`` (complex)."""
    a, b = line[:-1], line[1:]
    ab = b - a
    rel = points[:, None] - a[None, :]
    t = np.clip((rel * ab.conj()).real / np.maximum(np.abs(ab) ** 2, 1e-300), 0, 1)
    return np.abs(rel - t * ab).min(axis=1)


def assert_tip_follows(axis: np.ndarray, offset: float, outline: np.ndarray, tolerance: float,
                       samples: int = 4) -> np.ndarray:
    """The tip dragged along ``axis`` stays within ``tolerance`` of ``outline`` and passes
    every one of its vertices; returns the tip path."""
    tip = dragged_tip(axis, offset, samples)
    strays = distance_to_polyline(tip, outline)
    assert strays.max() <= tolerance, f"the tip strays {strays.max():.5f} mm from the outline"
    reached = np.abs(outline[:, None] - tip[None, :])
    assert reached.min(axis=1).max() <= tolerance, \
        f"the tip misses corner {outline[reached.min(axis=1).argmax()]} by {reached.min(axis=1).max():.5f} mm"
    return tip
