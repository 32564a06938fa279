"""Writing job files: job_to_toml reads back through parse_job as the same job, and builds the same design."""

from __future__ import annotations

import dataclasses
import math
import tomllib

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from foldfab.design import build_design
from foldfab.errors import FoldfabError
from foldfab.job import job_data, job_to_toml, load_job, parse_job, toml_text
from helpers import JOB_FOLDER, JOBS



def same_job(a, b) -> bool:
    return dataclasses.replace(a, text="") == dataclasses.replace(b, text="")


@pytest.mark.parametrize("path", JOBS, ids=[p.stem for p in JOBS])
def test_example_jobs_round_trip(path):
    job = load_job(path)
    text = job_to_toml(job)
    again = parse_job(text, path)
    assert same_job(again, job)
    assert job_to_toml(again) == text, "writing is stable"
    first, second = build_design(job, allow_penetration=True), build_design(again, allow_penetration=True)
    assert np.array_equal(first.crease_pattern.vertices, second.crease_pattern.vertices)
    assert np.array_equal(first.crease_pattern.assignment, second.crease_pattern.assignment)


def test_svg_paths_are_rewritten_for_another_folder(tmp_path):
    job = load_job(JOB_FOLDER / "vase-svg.toml")
    folder = tmp_path / "elsewhere" / "deeper"
    folder.mkdir(parents=True)
    text = job_to_toml(job, folder)
    moved = parse_job(text, folder / "vase.toml")
    assert moved.profile.svg.file == job.profile.svg.file
    assert tomllib.loads(text)["profile"]["svg"].startswith("../")


def test_data_is_a_copy_with_every_table():
    job = load_job(JOB_FOLDER / "hexagon-fig8a.toml")
    data = job_data(job)
    assert list(data) == ["design", "profile", "trajectory", "crease", "fabrication"]
    assert data["trajectory"] == {"template": "regular", "corners": 6, "radius": 40.0}
    data["fabrication"]["margin"] = 99
    assert job.fabrication["margin"] == 10


def test_three_d_polyline_and_open_trajectory():
    job = parse_job('[profile]\npoints = [[0, 0], [1, 2]]\n[trajectory]\ntemplate = "polyline"\n'
                    'points = [[0, 0, 0], [10, 0, 1], [10, 10, 2], [0, 10, 3], [0, 20, 4]]\n', "a/b.toml")
    assert same_job(parse_job(job_to_toml(job), "a/b.toml"), job)


def test_keys_and_strings_that_need_quotes():
    data = {"design": {"name": 'quote " back \\ tab \t newline \n del \x7f é'},
            "fabrication": {"layers": {"cut": {"force": 20, "passes": 2}}, "odd key": [1, 2.5, True, "x"]}}
    assert tomllib.loads(toml_text(data)) == data


@pytest.mark.parametrize("bad", [{"design": None}, {"design": {"name": None}}, {"design": {1: 2}},
                                 {"design": {"name": "\ud800"}}, [1, 2]])
def test_unwritable_values_are_errors(bad):
    with pytest.raises(FoldfabError):
        toml_text(bad)


scalars = (st.booleans() | st.integers(-2**63, 2**63 - 1) | st.floats(allow_nan=False)
           | st.text(st.characters(exclude_categories=("Cs",))))
values = st.recursive(scalars, lambda inner: st.lists(inner, max_size=6), max_leaves=20)
keys = st.text(st.characters(exclude_categories=("Cs",)), min_size=1, max_size=8)
tables = st.recursive(st.dictionaries(keys, values, max_size=4),
                      lambda inner: st.dictionaries(keys, values | inner, max_size=4), max_leaves=12)


@given(st.dictionaries(keys, tables, max_size=4))
def test_any_table_round_trips(data):
    back = tomllib.loads(toml_text(data))
    assert _normal(back) == _normal(data)


def _normal(value):
    """Floats compare by their bits' meaning (inf == inf), tuples as lists."""
    if isinstance(value, dict):
        return {k: _normal(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_normal(v) for v in value]
    if isinstance(value, float) and math.isinf(value):
        return ("inf", value > 0)
    return value


def test_saved_elsewhere_builds_the_same(tmp_path):
    job = load_job(JOB_FOLDER / "vase-svg.toml")
    target = tmp_path / "vase.toml"
    target.write_text(job_to_toml(job, tmp_path), encoding="utf-8")
    copied = load_job(target)
    assert copied.profile.svg.file == job.profile.svg.file, "the saved job still reads the original SVG"
    assert np.array_equal(build_design(copied).crease_pattern.vertices, build_design(job).crease_pattern.vertices)
