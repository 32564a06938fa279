"""A design split across sheets (issue 20): the example job on A4, its sheets, programs and marks."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from foldfab.design import load_design
from foldfab.devices import load_device
from foldfab.errors import FoldfabError
from foldfab.fabricate import fabricate, fabricate_sheets
from foldfab.fabrication.layout import reachable
from foldfab.fabrication.pieces import design_pieces, piece_design
from foldfab.fabrication.plan import Pass, Pause
from foldfab.fabrication.spec import MARKS, job_spec, parse_fabrication
from foldfab.formats import fold
from foldfab.job import load_job
from helpers import JOB_FOLDER
from helpers.pieces import assert_pieces_rebuild

LANTERN = JOB_FOLDER / "lantern-three-sheets.toml"


@pytest.fixture(scope="module")
def lantern():
    return load_design(LANTERN)


def test_the_example_is_three_sheets_long_and_splits_into_three_pieces_that_glue_back(lantern):
    device = load_device("hp7475a")
    spec = job_spec(lantern.job)
    assert lantern.crease_pattern.sheet_size[0] > 2.5 * spec.sheet[0]   # A4 landscape, 297 mm
    pieces = design_pieces(lantern, spec, *reachable(lantern, device, spec))
    assert [p.label for p in pieces] == ["1 OF 3", "2 OF 3", "3 OF 3"]
    assert_pieces_rebuild(lantern.crease_pattern, pieces)
    # every cut (and the seam) has a tab on one piece and its edge on the next, with one letter
    assert sorted((j.letter, j.tab) for p in pieces for j in p.joins) == [
        ("A", False), ("A", True), ("B", False), ("B", True), ("C", False), ("C", True)]
    assert all(p.marks for p in pieces)


def test_splitting_changes_neither_the_model_nor_the_fold_file(lantern, tmp_path):
    whole = tmp_path / "whole.toml"
    whole.write_text(LANTERN.read_text().replace('split = "auto"', ""))
    unsplit = load_design(whole)
    assert fold.dumps(unsplit.crease_pattern, "x") == fold.dumps(lantern.crease_pattern, "x")
    np.testing.assert_array_equal(unsplit.crease_pattern.vertices_3d, lantern.crease_pattern.vertices_3d)


def test_each_sheet_fits_and_draws_its_marks_with_the_scoring_tool_never_cutting(lantern):
    device = load_device("hp7475a")
    spec = replace(job_spec(lantern.job), strategy="perforate")
    sheets = fabricate_sheets(lantern, device, spec)
    assert len(sheets) == 3
    for fab in sheets:
        passes = {s.name: s for s in fab.plan.steps if isinstance(s, Pass)}
        assert list(passes) == ["valley", "marks", "mountain", "cut"]
        assert len(fab.plan.document.layers[MARKS[0]]) > 0
        scoring = device.tool_for("valley")   # the profile's, not the perforate strategy's cutting one
        assert (passes["marks"].tool.pen, passes["marks"].tool.force) == (scoring.pen, scoring.force)
        assert passes["cut"].tool.pen != passes["marks"].tool.pen or passes["cut"].tool.force != passes["marks"].tool.force
        assert fab.placement.scale == 1


def test_one_program_pauses_to_load_each_new_sheet(lantern):
    device = load_device("hp7475a")
    [fab] = fabricate_sheets(lantern, device, one_program=True)
    pauses = [s.message for s in fab.plan.steps if isinstance(s, Pause)]
    assert pauses == ["Load sheet 2 of 3 (piece 2), then continue.", "Load sheet 3 of 3 (piece 3), then continue."]
    assert [p.message for p in fab.program.pauses][-2:] == pauses
    separate = fabricate_sheets(lantern, device)
    strokes = sum(len(layer) for f in separate for layer in f.plan.document.layers.values())
    assert sum(len(layer) for layer in fab.plan.document.layers.values()) == strokes


def test_split_auto_is_not_needed_when_the_design_fits(lantern):
    device = load_device("hp7475a")
    assert len(fabricate_sheets(lantern, device, scale=0.3)) == 1
    assert len(fabricate_sheets(lantern, device, scale="fit")) == 1


def test_explicit_cuts_and_their_errors(lantern, tmp_path):
    device = load_device("hp7475a")
    spec = replace(job_spec(lantern.job), split=(4, 8), split_height=())
    assert [p.columns for p in design_pieces(lantern, spec)] == [(0, 4), (4, 8), (8, 11)]
    with pytest.raises(FoldfabError, match=r"lantern-three-sheets.toml: \[fabrication\]\.split: 11 is not a cut"):
        design_pieces(lantern, replace(spec, split=(11,)))
    with pytest.raises(FoldfabError, match=r"lantern-three-sheets.toml: .* even one panel"):
        fabricate_sheets(lantern, device, scale=20.0)
    # "auto" with a command that has no device needs the job's sheet
    with pytest.raises(FoldfabError, match=r"set \[fabrication\]\.sheet"):
        design_pieces(lantern, replace(spec, split="auto", sheet=None))


@pytest.mark.parametrize("table, message", [
    ({"split": "yes"}, r"\[fabrication\]\.split: expected \"auto\" .* got 'yes'"),
    ({"split": [0]}, r"\[fabrication\]\.split: expected .* got \[0\]"),
    ({"split": [2, 2]}, r"\[fabrication\]\.split: expected .*list of trajectory corners"),
    ({"split": [1.5]}, r"\[fabrication\]\.split: expected"),
    ({"split_height": "auto"}, r"\[fabrication\]\.split_height: expected a list of profile points"),
    ({"split_height": [True]}, r"\[fabrication\]\.split_height: expected"),
])
def test_bad_split_keys_are_named(table, message):
    with pytest.raises(FoldfabError, match=message):
        parse_fabrication(table, "job.toml")


def test_split_keys_parse():
    spec = parse_fabrication({"split": [8, 4], "split_height": [2]}, "job.toml")
    assert spec.split == (4, 8) and spec.split_height == (2,)
    assert parse_fabrication({"split": "auto"}, "job.toml").split == "auto"
    assert load_job(LANTERN).fabrication["split"] == "auto"


def test_pieces_fitted_to_the_sheet_share_one_scale(lantern):
    device = load_device("hp7475a")
    spec = replace(job_spec(lantern.job), split=(3, 7), scale="fit")
    sheets = fabricate_sheets(lantern, device, spec)
    assert len(sheets) == 3 and len({fab.placement.scale for fab in sheets}) == 1
    alone = [fabricate(piece_design(lantern, p), device, spec).placement.scale
             for p in design_pieces(lantern, spec)]
    assert sheets[0].placement.scale == pytest.approx(min(alone)) and max(alone) > 1.1 * min(alone)
