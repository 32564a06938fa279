"""The FOLD writer's text, written from numpy arrays, is json.dumps of the FOLD dictionary byte for byte."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from foldfab.design import load_design
from foldfab.formats import fold
from helpers import JOBS


def reference(cp, title: str) -> str:
    return json.dumps(fold.to_fold(cp, title), separators=(",", ":")) + "\n"


@pytest.mark.parametrize("job", JOBS, ids=[j.stem for j in JOBS])
def test_every_example_job_writes_what_json_writes(job):
    cp = load_design(job).crease_pattern
    assert fold.dumps(cp, "a \"title\" é") == reference(cp, "a \"title\" é")
    assert fold.to_fold(cp)["faces_vertices"] == cp.face_polygons()


floats = st.sampled_from([0.0, -0.0, 1.0, 0.1, 1e-5, 1e16, -2.5e-10, 123456.789012345, 3.0])


@settings(max_examples=200, deadline=None)
@given(hnp.arrays(np.float64, st.tuples(st.integers(0, 6), st.integers(1, 3)),
                  elements=floats | st.floats(-1e6, 1e6, allow_nan=False)))
def test_float_rows_are_written_as_json_writes_their_list(values):
    rows = fold._Rows(values)
    assert fold._array_text(rows) == json.dumps(values.tolist(), separators=(",", ":"))
    flat = fold._Rows(values[:, 0])
    assert fold._array_text(flat) == json.dumps(values[:, 0].tolist(), separators=(",", ":"))


@settings(max_examples=200, deadline=None)
@given(hnp.arrays(np.int64, st.tuples(st.integers(0, 6), st.just(4)), elements=st.integers(0, 3)))
def test_faces_with_repeated_corners_are_written_as_their_polygons(faces):
    rows = fold._Rows(faces, faces != np.roll(faces, 1, axis=1))
    polygons = [[v for i, v in enumerate(face) if v != face[i - 1]] for face in faces.tolist()]
    assert fold._array_text(rows) == json.dumps(polygons, separators=(",", ":"))


def test_non_finite_values_are_written_as_json_spells_them():
    values = np.array([[np.nan, 1.0], [np.inf, -np.inf]])
    assert fold._array_text(fold._Rows(values)) == json.dumps(values.tolist(), separators=(",", ":"))
