"""The studio's API in-process: designs by foldfab's core, validated requests, the file rule, HTTP guards."""

from __future__ import annotations

import contextlib
import copy
import http.client
import json
import shutil
import threading
from pathlib import Path

import numpy as np
import pytest

from foldfab.design import load_design, summary
from foldfab.job import job_data, load_job
from foldfab.studio.api import MAX_BODY, Studio, error_cause, pack, unpack
from foldfab.studio.server import StudioServer

JOBS = Path(__file__).resolve().parent.parent / "jobs"
PENETRATING = [[0, 0], [6, 10], [6, 0], [0, 10]]


@pytest.fixture
def folder(tmp_path):
    work = tmp_path / "work"
    work.mkdir()
    for name in ("hexagon-fig8a.toml", "vase-svg.toml", "vase-profile.svg"):
        shutil.copy(JOBS / name, work / name)
    return work


@pytest.fixture
def studio(folder):
    return Studio(folder, folder / "hexagon-fig8a.toml")


@pytest.fixture
def hexagon(folder):
    return job_data(load_job(folder / "hexagon-fig8a.toml"))


def call(studio: Studio, path: str, body: dict | None = None, method: str = "POST"):
    """(status, JSON or (header, arrays))."""
    response = studio.handle(method, path, b"" if body is None else json.dumps(body).encode())
    if response.content_type == "application/octet-stream":
        return response.status, unpack(response.body)
    return response.status, json.loads(response.body)


def design(studio: Studio, job: dict, **extra):
    return call(studio, "/api/design", {"job": job, "path": str(studio.job_path), **extra})


# --- state and designs -------------------------------------------------------------------------


def test_state_has_the_job_the_devices_and_the_queue(studio, hexagon, folder):
    status, state = call(studio, "/api/state", method="GET")
    assert status == 200
    assert state["job"] == hexagon
    assert state["path"] == str(folder / "hexagon-fig8a.toml") and state["display"] == "hexagon-fig8a.toml"
    assert "grbl" in state["devices"] and state["queue"]["available"]


def test_a_missing_job_file_is_a_new_design(folder):
    status, state = call(Studio(folder, folder / "new.toml"), "/api/state", method="GET")
    assert status == 200 and state["job"]["design"]["name"] == "new"
    assert design(Studio(folder, folder / "new.toml"), state["job"])[0] == 200


def test_design_is_what_the_core_builds(studio, hexagon, folder):
    status, (header, arrays) = design(studio, hexagon, seq=7)
    assert status == 200 and header["seq"] == 7
    expected = load_design(folder / "hexagon-fig8a.toml")
    assert header["summary"] == summary(expected)
    cp = expected.crease_pattern
    assert np.allclose(arrays["cp_vertices"], cp.vertices, atol=1e-4)
    assert np.allclose(arrays["model_vertices"], cp.vertices_3d, atol=1e-4)
    assert np.array_equal(arrays["triangles"], cp.triangles()[0])
    assert np.array_equal(arrays["profile"], np.array(hexagon["profile"]["points"], float))
    assert arrays["trajectory"].shape == (8, 3) and arrays["planes"].shape == (8, 6)
    assert arrays["paths"].shape == (5, 8, 3) and arrays["penetrating"].shape == (0, 4)
    # Edges come grouped F, V, M, B, each group as in the crease pattern.
    groups = header["edge_groups"]
    assert list(groups) == ["F", "V", "M", "B"] and sum(c for _, c in groups.values()) == len(cp.edges)
    for kind, (start, count) in groups.items():
        assert sorted(map(tuple, arrays["edges"][start:start + count].tolist())) == \
            sorted(map(tuple, cp.edges[cp.assignment == kind].tolist()))
    assert header["fit"] is None


def test_pack_round_trip_keeps_alignment():
    arrays = {"a": np.arange(3, dtype=np.uint8), "b": np.linspace(0, 1, 5), "c": np.ones((2, 3), np.float32)}
    data = pack({"x": 1}, arrays)
    header, back = unpack(data)
    assert header["x"] == 1
    assert (8 + int.from_bytes(data[4:8], "little")) % 8 == 0, "the arrays start 8-byte aligned"
    for name, array in arrays.items():
        assert np.array_equal(back[name], array) and back[name].dtype == array.dtype
        assert header["arrays"][name]["offset"] % 8 == 0


def test_svg_profile_design(studio, folder):
    job = job_data(load_job(folder / "vase-svg.toml"))
    status, (header, arrays) = call(studio, "/api/design", {"job": job, "path": str(folder / "vase-svg.toml")})
    assert status == 200 and len(arrays["profile"]) > 10
    assert header["summary"] == summary(load_design(folder / "vase-svg.toml"))


def test_fit_on_a_device(studio, hexagon):
    status, (header, _) = design(studio, hexagon, device="grbl")
    fit = header["fit"]
    assert status == 200 and fit["ok"] and fit["device"] == "grbl" and fit["message"].startswith("fits grbl")
    hexagon["fabrication"]["sheet"] = [100, 100]
    status, (header, _) = design(studio, hexagon, device="grbl")
    assert status == 200 and not header["fit"]["ok"] and "largest scale that fits" in header["fit"]["message"]
    status, (header, _) = design(studio, hexagon, device="no-such-plotter")
    assert not header["fit"]["ok"] and "unknown device" in header["fit"]["message"]


# --- invalid designs ---------------------------------------------------------------------------


def test_odd_corners_point_at_the_corners(studio, hexagon):
    hexagon["trajectory"]["corners"] = 7
    status, answer = design(studio, hexagon)
    assert status == 400 and "even number of corners" in answer["error"]
    assert answer["cause"] == {"view": "trajectory", "field": "trajectory.corners"}
    assert len(answer["polylines"]["trajectory"]) == 9, "the 7-gon the user asked for, to draw"
    assert answer["polylines"]["profile"] == hexagon["profile"]["points"]


def test_negative_length_points_at_the_profile_point(studio, hexagon):
    hexagon["profile"]["points"][3] = [14, 30]
    hexagon["crease"]["glue_tab"] = 0
    status, answer = design(studio, hexagon)
    assert status == 400 and "reduce u of profile point 3" in answer["error"]
    assert answer["cause"] == {"view": "profile", "point": 3}


def test_job_mistakes_name_the_key(studio, hexagon):
    bad = copy.deepcopy(hexagon)
    bad["trajectory"]["radius"] = -1
    status, answer = design(studio, bad)
    assert status == 400 and "[trajectory].radius" in answer["error"]
    assert answer["cause"] == {"view": "trajectory", "field": "trajectory.radius"}
    bad = copy.deepcopy(hexagon)
    bad["profile"]["points"][2] = ["a", 1]
    status, answer = design(studio, bad)
    assert status == 400 and answer["cause"] == {"view": "profile", "field": "profile.points", "point": 2}
    bad = copy.deepcopy(hexagon)
    bad["crease"]["colour"] = "red"
    status, answer = design(studio, bad)
    assert status == 400 and answer["cause"]["view"] == "creases" and "unknown key" in answer["error"]
    status, answer = design(studio, {**hexagon, "profile": None})
    assert status == 400 and "[profile]: expected a table" in answer["error"]


def test_penetration_is_an_error_with_the_faces_unless_allowed(studio, hexagon):
    hexagon["profile"]["points"] = PENETRATING
    hexagon["crease"]["glue_tab"] = 0
    status, answer = design(studio, hexagon)
    assert status == 400 and answer["error"].count("penetration") >= 1 and "allow penetration" in answer["error"]
    assert answer["cause"] == {"view": "model"}
    quads = np.array(answer["penetrating"]).reshape(-1, 4, 3)
    assert len(quads) > 0
    status, (header, arrays) = design(studio, hexagon, allow_penetration=True)
    assert status == 200 and header["summary"]["penetrations"] > 0 and header["summary"]["warnings"]
    assert len(arrays["penetrating"]) == len(quads)


@pytest.mark.parametrize("body, message", [
    (b"not json", "not valid JSON"), (b"[1, 2]", "expected a JSON object"), (b'{"job": NaN}', "NaN"),
    (b"{}", "missing field 'job'"), (b'{"job": []}', "'job' must be an object"),
    (b'{"job": {}, "path": 3}', "'path' must be a string"),
    (b'{"job": {}, "allow_penetration": 1}', "must be true or false"),
    (b'{"job": {}, "seq": true}', "'seq' must be a whole number, got a boolean"),
    (b'{"job": {"design": {"name": null}}}', "cannot be written to TOML"),
    (b"\xff\xfe", "not valid JSON"), (b"[" * 100_000 + b"]" * 100_000, "JSON"),
])
def test_requests_are_validated(studio, body, message):
    response = studio.handle("POST", "/api/design", body)
    assert response.status == 400
    assert message in json.loads(response.body)["error"]


def test_deeply_nested_job_is_refused(studio):
    job = {"design": {"name": "x"}, "fabrication": {"a": [[[[[[[[[[[[[[[[[[[[[[1]]]]]]]]]]]]]]]]]]]]]]}}
    nested = json.dumps({"job": job}).replace("[1]", "[" * 900 + "1" + "]" * 900)
    response = studio.handle("POST", "/api/design", nested.encode())
    assert response.status == 400


def test_routes_and_sizes(studio):
    assert studio.handle("GET", "/api/nothing").status == 404
    assert studio.handle("GET", "/api/design").status == 405
    response = studio.handle("POST", "/api/design", b" " * (MAX_BODY + 1))
    assert response.status == 413


# --- files -------------------------------------------------------------------------------------


def save(studio, job, target, **extra):
    return call(studio, "/api/save", {"job": job, "path": str(studio.job_path), "target": str(target), **extra})


def test_saved_job_builds_identically(studio, hexagon, folder):
    hexagon["profile"]["points"][1] = [5.5, 10]
    hexagon["crease"]["flat_angle"] = 3
    status, (header, arrays) = design(studio, hexagon)
    assert status == 200
    status, answer = save(studio, hexagon, "mine.toml")
    assert status == 200 and answer["written"] == str(folder / "mine.toml") and answer["display"] == "mine.toml"
    built = load_design(folder / "mine.toml")
    assert summary(built)["creases"] == header["summary"]["creases"]
    assert np.allclose(built.crease_pattern.vertices, arrays["cp_vertices"], atol=1e-4)
    assert answer["job"] == job_data(load_job(folder / "mine.toml"))
    # Saving over it needs the user's yes.
    status, answer = save(studio, hexagon, "mine.toml")
    assert status == 409 and answer["exists"] and "replace it?" in answer["error"]
    assert save(studio, hexagon, "mine.toml", overwrite=True)[0] == 200


def test_saving_an_svg_job_elsewhere_rewrites_its_paths(studio, folder, tmp_path):
    job = job_data(load_job(folder / "vase-svg.toml"))
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    status, answer = call(studio, "/api/save", {"job": job, "path": str(folder / "vase-svg.toml"),
                                                "target": str(elsewhere / "vase.toml")})
    assert status == 200 and answer["job"]["profile"]["svg"] == "../work/vase-profile.svg"
    assert summary(load_design(elsewhere / "vase.toml"))["creases"] == summary(load_design(folder / "vase-svg.toml"))["creases"]


def test_the_file_rule(studio, hexagon, folder, tmp_path):
    status, answer = save(studio, hexagon, "../outside.toml")
    assert status == 400 and "must stay inside the folder the studio was started in" in answer["error"]
    assert not (tmp_path / "outside.toml").exists()
    (folder / "link").symlink_to(tmp_path)
    status, answer = save(studio, hexagon, "link/escaped.toml")
    assert status == 400 and not (tmp_path / "escaped.toml").exists(), "links are followed before the check"
    status, answer = save(studio, hexagon, str(tmp_path / "typed.toml"))
    assert status == 200 and (tmp_path / "typed.toml").is_file(), "an absolute path is the user's choice"
    assert save(studio, hexagon, "missing/x.toml")[1]["error"].endswith("does not exist; create it first")
    assert "ending in .toml" in save(studio, hexagon, "x.txt")[1]["error"]
    assert "type a file name" in save(studio, hexagon, "  ")[1]["error"]
    (folder / "dir.toml").mkdir()
    assert "is a folder" in save(studio, hexagon, "dir.toml")[1]["error"]


def test_the_job_folder_is_allowed_too(tmp_path, hexagon):
    start, jobs = tmp_path / "start", tmp_path / "jobs"
    start.mkdir()
    jobs.mkdir()
    studio = Studio(start, jobs / "a.toml")
    status, answer = call(studio, "/api/save", {"job": hexagon, "path": str(jobs / "a.toml"), "target": "../jobs/b.toml"})
    assert status == 200 and (jobs / "b.toml").is_file()


def test_open_and_list(studio, folder, tmp_path):
    status, answer = call(studio, "/api/open", {"target": "vase-svg.toml", "path": str(studio.job_path)})
    assert status == 200 and answer["job"] == job_data(load_job(folder / "vase-svg.toml"))
    status, answer = call(studio, "/api/open", {"target": "nothing.toml"})
    assert status == 400 and "job file not found" in answer["error"]
    (tmp_path / "secret.toml").write_text("x")
    assert call(studio, "/api/open", {"target": "../secret.toml"})[0] == 400
    status, answer = call(studio, "/api/files", {"path": str(studio.job_path)})
    assert status == 200 and answer["files"] == ["hexagon-fig8a.toml", "vase-svg.toml"]


@pytest.mark.parametrize("suffix, first", [(".fold", b"{"), (".svg", b"<?xml"), (".cp", b"1 "),
                                           (".stl", None), (".obj", None), (".ply", b"ply"), (".glb", b"glTF")])
def test_export_every_kind(studio, hexagon, folder, suffix, first):
    target = folder / f"out{suffix}"
    status, answer = call(studio, "/api/export", {"job": hexagon, "path": str(studio.job_path), "target": target.name})
    assert status == 200 and answer["written"] == str(target)
    data = target.read_bytes()
    assert data and (first is None or data.startswith(first))


def test_export_refuses_unknown_kinds_and_penetration(studio, hexagon):
    status, answer = call(studio, "/api/export", {"job": hexagon, "target": "out.pdf"})
    assert status == 400 and "expected a file name ending in .fold" in answer["error"]
    hexagon["profile"]["points"] = PENETRATING
    hexagon["crease"]["glue_tab"] = 0
    status, answer = call(studio, "/api/export", {"job": hexagon, "target": "out.fold"})
    assert status == 400 and answer["cause"]["view"] == "model"
    status, answer = call(studio, "/api/export", {"job": hexagon, "target": "out.fold", "allow_penetration": True})
    assert status == 200


def test_preview(studio, hexagon):
    status, answer = call(studio, "/api/preview", {"job": hexagon, "device": "grbl"})
    assert status == 200 and answer["svg"].startswith("<?xml") and 'id="legend"' in answer["svg"]
    assert answer["device"] == "grbl" and answer["program_bytes"] > 0
    status, answer = call(studio, "/api/preview", {"job": hexagon})
    assert status == 400 and "choose a device" in answer["error"]


def test_queue_add(studio, hexagon, tmp_path, monkeypatch):
    from foldfab.queue import SqliteQueueStore

    monkeypatch.setenv("FOLDFAB_QUEUE", str(tmp_path / "queue.sqlite3"))
    status, answer = call(studio, "/api/queue", {"job": hexagon, "device": "grbl", "port": "sim://grbl", "copies": 2})
    assert status == 200 and len(answer["ids"]) == 2 and answer["port"] == "sim://grbl"
    store = SqliteQueueStore(tmp_path / "queue.sqlite3")
    try:
        jobs = store.jobs()
        assert [j.state for j in jobs] == ["queued", "queued"] and jobs[0].name == hexagon["design"]["name"]
        assert store.snapshot(jobs[0].id).job_text.startswith("[design]")
    finally:
        store.close()
    status, answer = call(studio, "/api/queue", {"job": hexagon, "device": "grbl", "copies": 0})
    assert status == 400 and "'copies' must be from 1" in answer["error"]


def test_error_causes():
    assert error_cause("penetration: 2 pair(s)") == {"view": "model"}
    assert error_cause("[crease].glue_tab: 5 mm is longer") == {"view": "creases", "field": "crease.glue_tab"}
    assert error_cause("[fabrication].sheet: expected") == {"view": "creases", "field": "fabrication.sheet"}
    assert error_cause("profile: points 2 and 3 are the same point") == {"view": "profile", "point": 2}
    assert error_cause("profile segment 4-5 collapses") == {"view": "profile", "point": 4}
    assert error_cause("trajectory: the path turns back on itself at point 3") == {"view": "trajectory"}
    assert error_cause("something else") == {"view": "file"}


# --- HTTP --------------------------------------------------------------------------------------


@contextlib.contextmanager
def serving(server: StudioServer):
    """``server`` answering in a thread until the block ends."""
    thread = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True)
    thread.start()
    try:
        yield server
    finally:
        server.shutdown()
        server.server_close()
        thread.join(timeout=10)


@pytest.fixture
def server(studio):
    with serving(StudioServer(studio)) as server:
        yield server


def request(server, method, path, body=b"", headers=None):
    connection = http.client.HTTPConnection("127.0.0.1", server.server_address[1], timeout=30)
    try:
        connection.request(method, path, body, {"Host": f"127.0.0.1:{server.server_address[1]}", **(headers or {})})
        response = connection.getresponse()
        return response.status, response.getheader("Content-Type"), response.read()
    finally:
        connection.close()


def test_http_page_static_and_token(server, hexagon):
    assert server.server_address[0] == "127.0.0.1"
    status, kind, page = request(server, "GET", "/")
    assert status == 200 and kind.startswith("text/html") and server.token.encode() in page
    status, kind, data = request(server, "GET", "/static/vendor/three.module.min.js")
    assert status == 200 and kind.startswith("text/javascript") and b"three.core.min.js" in data
    for path in ("/static/../api.py", "/static/%2e%2e/api.py", "/static/nothing.js", "/elsewhere"):
        assert request(server, "GET", path)[0] == 404
    body = json.dumps({"job": hexagon}).encode()
    json_type = {"Content-Type": "application/json"}
    assert request(server, "POST", "/api/design", body, json_type)[0] == 403
    assert request(server, "POST", "/api/design", body, {**json_type, "X-Foldfab-Token": "guess"})[0] == 403
    token = {**json_type, "X-Foldfab-Token": server.token}
    status, kind, data = request(server, "POST", "/api/design", body, token)
    assert status == 200 and kind == "application/octet-stream" and unpack(data)[0]["summary"]["faces"] == 32
    assert request(server, "POST", "/api/design", body, {**token, "Content-Type": "text/plain"})[0] == 415
    assert request(server, "POST", "/api/design", body, {**token, "Host": "evil.example:80"})[0] == 403
    status, _, data = request(server, "GET", "/api/state", headers={"X-Foldfab-Token": server.token})
    assert status == 200 and json.loads(data)["job"] == hexagon


def test_http_refuses_a_huge_body_before_reading_it(server):
    connection = http.client.HTTPConnection("127.0.0.1", server.server_address[1], timeout=30)
    try:
        connection.putrequest("POST", "/api/design", skip_host=True)
        connection.putheader("Host", f"127.0.0.1:{server.server_address[1]}")
        connection.putheader("Content-Type", "application/json")
        connection.putheader("X-Foldfab-Token", server.token)
        connection.putheader("Content-Length", str(MAX_BODY + 1))
        connection.endheaders()
        response = connection.getresponse()
        assert response.status == 413 and "too large" in json.loads(response.read())["error"]
    finally:
        connection.close()


def test_cli_starts_the_server(tmp_path):
    import subprocess
    import sys
    import urllib.request

    shutil.copy(JOBS / "hexagon-fig8a.toml", tmp_path / "h.toml")
    process = subprocess.Popen([sys.executable, "-m", "foldfab", "studio", "h.toml", "--no-browser"],
                               cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = process.stdout.readline()
        assert line.startswith("foldfab studio: http://127.0.0.1:"), line + process.stderr.read()
        url = line.split()[2]
        with urllib.request.urlopen(url, timeout=30) as page:
            assert b"foldfab studio" in page.read()
    finally:
        process.terminate()
        process.wait(timeout=30)


def test_cli_refuses_a_broken_job(tmp_path):
    import subprocess
    import sys

    (tmp_path / "bad.toml").write_text('[profile]\npoints = 3\n[trajectory]\ntemplate = "regular"\ncorners = 6\nradius = 4\n')
    run = subprocess.run([sys.executable, "-m", "foldfab", "studio", "bad.toml", "--no-browser"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 2 and "bad.toml" in run.stderr and "[profile].points" in run.stderr
