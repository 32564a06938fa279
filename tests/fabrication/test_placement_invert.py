"""Placement.invert undoes Placement.apply: the studio draws the sheet's outline round the
crease pattern by mapping the sheet's corners back."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from foldfab.fabrication.placement import Placement

finite = st.floats(-1e4, 1e4, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(scale=st.floats(1e-3, 1e3), rotated=st.booleans(), origin=st.tuples(finite, finite), lo=st.tuples(finite, finite),
       points=st.lists(st.tuples(finite, finite), min_size=1, max_size=20))
def test_invert_undoes_apply(scale, rotated, origin, lo, points):
    placement = Placement(scale, rotated, complex(*origin), complex(*lo), (1.0, 1.0))
    p = np.array([complex(*q) for q in points])
    assert np.allclose(placement.invert(placement.apply(p)), p, atol=1e-9 * (1 + np.abs(p).max() + abs(complex(*lo))) / min(scale, 1))
    assert np.allclose(placement.apply(placement.invert(p)), p, atol=1e-9 * (1 + np.abs(p).max() + abs(complex(*origin))) * max(scale, 1) / min(scale, 1))
