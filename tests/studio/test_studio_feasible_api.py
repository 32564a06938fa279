"""The studio API's feasible band and template fitting (foldfab.geometry.feasible on the server)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from foldfab.geometry import templates
from foldfab.geometry.feasible import Feasible
from foldfab.studio.api import NEW_JOB, Studio
from foldfab.studio.wire import unpack


def call(studio: Studio, path: str, body: dict):
    response = studio.handle("POST", path, json.dumps(body).encode())
    if response.content_type == "application/octet-stream":
        return response.status, unpack(response.body)[0]
    return response.status, json.loads(response.body)


def test_every_design_answer_carries_the_band_valid_or_not(tmp_path):
    studio = Studio(tmp_path)
    job = {**NEW_JOB, "trajectory": {"template": "regular", "corners": 8, "radius": 40.0}}
    status, answer = call(studio, "/api/design", {"job": job})
    assert status == 400 and "at most 6.341" in answer["error"]
    band = np.array(answer["feasible"])
    assert band[:, 0].max() == pytest.approx(6.3405, abs=1e-4)
    assert np.all(Feasible.of(templates.regular(8, 40)).lengths(band) >= -1e-5)   # rounded to 1e-6 mm
    job["profile"] = {**job["profile"], "offset": [-3.0, 0.0]}     # the band is where points + offset may go
    status, header = call(studio, "/api/design", {"job": job})
    assert status == 200 and np.array(header["feasible"])[:, 0].max() == pytest.approx(6.3405, abs=1e-4)


def test_fit_template_grows_clamps_and_leaves_polylines(tmp_path):
    studio = Studio(tmp_path)
    job = {**NEW_JOB, "trajectory": {"template": "regular", "corners": 8, "radius": 40.0}}
    status, answer = call(studio, "/api/fit-template", {"job": job, "changed": "corners"})
    assert status == 200 and answer["trajectory"] == {"template": "regular", "corners": 8, "radius": 50.5}
    job["trajectory"] = {"template": "regular", "corners": 6, "radius": 10.0}
    status, answer = call(studio, "/api/fit-template", {"job": job, "changed": "radius", "previous": 40})
    assert answer["trajectory"]["radius"] == pytest.approx(27.713, abs=2e-3) and "stops at" in answer["note"]
    polyline = {"template": "polyline", "points": [[0, 0], [30, 0], [30, 30], [0, 0]]}
    status, answer = call(studio, "/api/fit-template", {"job": {**job, "trajectory": polyline}})
    assert status == 200 and answer == {"trajectory": polyline, "note": ""}
    for bad in ({"changed": 3}, {"previous": "x"}, {"previous": True}):
        status, answer = call(studio, "/api/fit-template", {"job": job, **bad})
        assert status == 400 and answer["error"].startswith("request:")


def test_fold_answers_the_part_way_state_on_the_model_vertices(tmp_path):
    from foldfab.studio.wire import unpack as unpack_answer

    studio = Studio(tmp_path)
    design = studio.handle("POST", "/api/design", json.dumps({"job": NEW_JOB}).encode())
    folded = unpack_answer(design.body)[1]["model_vertices"]
    for t, flat in ((0, True), (0.5, False), (1, False)):
        response = studio.handle("POST", "/api/fold", json.dumps({"job": NEW_JOB, "t": t}).encode())
        header, arrays = unpack_answer(response.body)
        assert response.status == 200 and arrays["vertices"].shape == folded.shape
        centred = arrays["vertices"] - arrays["vertices"].mean(axis=0)
        assert (np.linalg.svd(centred, compute_uv=False)[-1] < 1e-3) == flat
        assert (header["max_strain"] > 0.01) == (t == 0.5)
    np.testing.assert_allclose(arrays["vertices"], folded, atol=1e-4)
    for bad in (-0.1, 1.5, "1", True):
        status, answer = call(studio, "/api/fold", {"job": NEW_JOB, "t": bad})
        assert status == 400 and answer["error"].startswith("request:")


def test_generate_profile_clamps_to_the_band_and_refuses_bad_requests(tmp_path):
    studio = Studio(tmp_path)
    job = {**NEW_JOB, "trajectory": {"template": "regular", "corners": 8, "radius": 40.0}}
    status, answer = call(studio, "/api/generate-profile", {"job": job, "kind": "sine", "amplitude": 20,
                                                            "period": 10, "points": 81})
    points = np.array(answer["points"])
    assert status == 200 and len(points) == 81 and points[:, 0].max() <= 6.3405
    status, design = call(studio, "/api/design", {"job": {**job, "profile": {"points": answer["points"],
                                                                             "offset": [0, 0]}}})
    assert status == 200
    for bad, message in (({"kind": "zigzag"}, "unknown kind"), ({"kind": "sine", "points": 1}, "'points' must be"),
                         ({"kind": "sine", "period": -1}, "period must be"), ({"kind": 3}, "request:")):
        status, answer = call(studio, "/api/generate-profile", {"job": job, **bad})
        assert status == 400 and message in answer["error"]
