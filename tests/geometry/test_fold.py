"""Part-way folded states: flat at 0, the folded model at 1, strain only in between."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from foldfab.geometry import templates
from foldfab.geometry.crease_pattern import build_crease_pattern
from foldfab.geometry.feasible import Feasible
from foldfab.geometry.fold import fold_state
from foldfab.geometry.reflection import reflect


def _pattern(n: int, radius: float, wave: float, rows: int, tab: float):
    trajectory = templates.regular(2 * n, radius)
    heights = np.linspace(0.0, 10.0 * rows, rows + 1)
    profile = np.column_stack([wave * (np.arange(rows + 1) % 2), heights])
    region = Feasible.of(trajectory)
    margin = np.full(len(region.c0), 0.01)
    margin[0] += tab                                  # the glue tab lies on the first segment
    return build_crease_pattern(reflect(region.clamp(profile, margin), trajectory), glue_tab=tab)


patterns = st.builds(_pattern, st.integers(2, 8), st.floats(20, 120), st.floats(-6, 6), st.integers(1, 6),
                     st.sampled_from([0.0, 4.0]))


def _sheet_distances(points: np.ndarray) -> np.ndarray:
    return np.linalg.norm(points[:, None] - points[None], axis=2)


@settings(max_examples=30, deadline=None)
@given(patterns)
def test_at_zero_a_flat_isometric_sheet_and_at_one_the_folded_model(cp):
    flat = fold_state(cp, 0.0)
    centred = flat.vertices - flat.vertices.mean(axis=0)
    assert np.linalg.svd(centred, compute_uv=False)[-1] < 1e-6 * max(1.0, np.abs(centred).max())   # one plane
    sheet = np.column_stack([cp.vertices, np.zeros(len(cp.vertices))])
    np.testing.assert_allclose(_sheet_distances(flat.vertices), _sheet_distances(sheet), atol=1e-6)
    assert flat.face_strain.max() < 1e-9
    folded = fold_state(cp, 1.0)
    np.testing.assert_allclose(folded.vertices, cp.vertices_3d, atol=1e-6 * max(1.0, np.abs(cp.vertices_3d).max()))
    assert folded.face_strain.max() < 1e-9


def test_a_column_half_folded_is_strained():
    cp = _pattern(3, 40.0, 8.0, 4, 0.0)
    half = fold_state(cp, 0.5)
    assert half.face_strain.max() > 0.01          # a closed column cannot turn all its creases halfway
    assert half.vertex_strain.max() == pytest.approx(half.face_strain.max())
    assert np.all(np.isfinite(half.vertices))
