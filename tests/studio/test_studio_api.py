"""The studio's API in-process: designs by foldfab's core, validated requests, the file rule, HTTP guards."""

from __future__ import annotations

import copy
import http.client
import json
import shutil
import socket
import struct
import threading
import time

import numpy as np
import pytest

from foldfab.design import load_design, summary
from foldfab.job import job_data, load_job
from foldfab.studio.api import MAX_BODY, Studio, error_cause
from foldfab.studio.wire import pack, unpack
from foldfab.studio.server import StudioServer
from helpers import JOB_FOLDER
from helpers.http import exchange, raw_request, refusals, responses, serving, smuggled

PENETRATING = [[0, 0], [6, 10], [6, 0], [0, 10]]


@pytest.fixture
def folder(tmp_path):
    work = tmp_path / "work"
    work.mkdir()
    for name in ("hexagon-fig8a.toml", "vase-svg.toml", "vase-profile.svg"):
        shutil.copy(JOB_FOLDER / name, work / name)
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
    from foldfab.queue.sqlite import SqliteQueueStore

    monkeypatch.setenv("FOLDFAB_QUEUE", str(tmp_path / "queue.sqlite3"))
    status, answer = call(studio, "/api/queue", {"job": hexagon, "device": "grbl", "port": "sim://grbl", "copies": 2})
    assert status == 200 and len(answer["ids"]) == 2 and answer["port"] == "sim://grbl"
    assert answer["where"] == "at sim://grbl"
    status, answer = call(studio, "/api/queue", {"job": hexagon, "device": "grbl"})  # no port: as queue add
    assert status == 200 and answer["where"].startswith("for any plotter of it")
    store = SqliteQueueStore(tmp_path / "queue.sqlite3")
    try:
        jobs = store.jobs()
        assert [j.state for j in jobs] == ["queued"] * 3 and jobs[0].name == hexagon["design"]["name"]
        assert [j.any_plotter for j in jobs] == [False, False, True]
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


@pytest.fixture
def server(studio):
    with serving(StudioServer(studio)) as server:
        yield server


def request(server, method, path, body=b"", headers=None):
    """(status, Content-Type, body); a POST comes from the studio's own page (its ``Origin``) unless told."""
    host = f"127.0.0.1:{server.server_address[1]}"
    own = {"Host": host, **({"Origin": f"http://{host}"} if method == "POST" else {})}
    connection = http.client.HTTPConnection("127.0.0.1", server.server_address[1], timeout=30)
    try:
        connection.request(method, path, body, {**own, **(headers or {})})
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
        connection.putheader("Origin", f"http://127.0.0.1:{server.server_address[1]}")
        connection.putheader("Content-Type", "application/json")
        connection.putheader("X-Foldfab-Token", server.token)
        connection.putheader("Content-Length", str(MAX_BODY + 1))
        connection.endheaders()
        response = connection.getresponse()
        assert response.status == 413 and "too large" in json.loads(response.read())["error"]
    finally:
        connection.close()


# --- raw HTTP: smuggling, framing, origins, timeouts (issue 17) ------------------------------------


@pytest.mark.parametrize("kind", ["host", "token", "method", "content type", "no length", "chunked", "two lengths",
                                  "junk length", "body on GET", "two hosts", "foreign origin"])
def test_a_refused_requests_body_is_never_read_as_a_request(server, hexagon, folder, kind):
    data, status = refusals(server, smuggled(server, hexagon))[kind]
    answered = responses(exchange(server, data))
    assert [s for s, _, _ in answered] == [status], "one refusal, and the smuggled requests are never answered"
    assert answered[0][1]["connection"] == ["close"]
    assert server.token.encode() not in answered[0][2]
    assert not (folder / "smuggled.toml").exists()


def test_a_refused_request_is_answered_then_closed_even_before_its_body_arrives(server):
    with socket.create_connection(("127.0.0.1", server.server_address[1]), timeout=20) as sock:
        sock.sendall(raw_request(server, "POST", "/api/save", b"", host="evil.example", length="100"))
        reply = sock.makefile("rb").read()  # the server closes without waiting for the 100 bytes
    assert reply.startswith(b"HTTP/1.1 403 ")


@pytest.mark.parametrize("headers", ["X-A: b\r\n c\r\n{host}", " {host}", "Host : {port}\r\n{host}",
                                     "X: y\r\nbad line\r\n{host}", "{host}\r\nX-\x00: 1"])
def test_malformed_header_lines_are_refused(server, headers):
    host = f"Host: 127.0.0.1:{server.server_address[1]}"
    data = f"GET / HTTP/1.1\r\n{headers.format(host=host, port=server.server_address[1])}\r\n\r\n"
    answered = responses(exchange(server, data.encode("latin-1") + raw_request(server, "GET", "/")))
    assert [s for s, _, _ in answered] == [400] and server.token.encode() not in answered[0][2]


def test_an_absolute_request_target_is_refused(server):
    port = server.server_address[1]
    data = raw_request(server, "GET", f"http://127.0.0.1:{port}/") + raw_request(server, "GET", "/")
    assert [s for s, _, _ in responses(exchange(server, data))] == [400]


def test_a_foreign_origin_or_site_cannot_post(server, hexagon):
    body = json.dumps({"job": hexagon}).encode()
    token = {"Content-Type": "application/json", "X-Foldfab-Token": server.token}
    port = server.server_address[1]
    assert request(server, "POST", "/api/design", body, {**token, "Origin": "http://evil.example"})[0] == 403
    assert request(server, "POST", "/api/design", body, {**token, "Origin": "null"})[0] == 403
    assert request(server, "POST", "/api/design", body, {**token, "Sec-Fetch-Site": "cross-site"})[0] == 403
    assert request(server, "POST", "/api/design", body, {**token, "Sec-Fetch-Site": "same-site"})[0] == 403
    assert request(server, "GET", "/api/state", headers={"X-Foldfab-Token": server.token,
                                                         "Origin": "http://evil.example"})[0] == 403
    no_origin = raw_request(server, "POST", "/api/design", body, token=server.token, origin=None)
    assert [s for s, _, _ in responses(exchange(server, no_origin))] == [403], "a POST must name its origin"
    for origin in (f"http://127.0.0.1:{port}", f"http://localhost:{port}"):
        headers = {**token, "Origin": origin, "Sec-Fetch-Site": "same-origin"}
        assert request(server, "POST", "/api/design", body, headers)[0] == 200


def test_the_token_is_read_only_from_its_header(server):
    assert request(server, "GET", f"/api/state?token={server.token}")[0] == 403
    assert request(server, "GET", f"/api/state?X-Foldfab-Token={server.token}")[0] == 403
    assert request(server, "GET", "/api/state", headers={"X-Foldfab-Token": server.token})[0] == 200


def test_a_non_ascii_token_is_a_403(server):
    data = raw_request(server, "GET", "/api/state").replace(b"\r\n\r\n", "\r\nX-Foldfab-Token: é€\r\n\r\n".encode())
    answered = responses(exchange(server, data))
    assert [s for s, _, _ in answered] == [403] and "token" in json.loads(answered[0][2])["error"]
    assert request(server, "GET", "/api/state", headers={"X-Foldfab-Token": server.token})[0] == 200


@pytest.mark.parametrize("data", [b"GET / HTTP/1.1\r\nHost: evil.example\r\n\r\n", b"GET /\x00 HTTP/1.1\r\n\r\n",
                                  b"GARBAGE\r\n\r\n", b"PUT / HTTP/1.1\r\n\r\n", "{}"])
def test_every_response_forbids_framing(server, data):
    if data == "{}":
        data = raw_request(server, "GET", "/")
    for status, headers, _ in responses(exchange(server, data)):
        assert headers["x-frame-options"] == ["DENY"], status
        assert "frame-ancestors 'none'" in headers["content-security-policy"][0], status
    for path in ("/", "/static/studio.js", "/api/state", "/nothing"):
        for status, headers, _ in responses(exchange(server, raw_request(server, "GET", path, token=server.token))):
            assert headers["x-frame-options"] == ["DENY"] and headers["content-security-policy"], (path, status)


def test_a_slow_or_idle_client_times_out(studio):
    with serving(StudioServer(studio, request_timeout=0.3)) as server:
        for data in (b"", b"GET / HTTP/1.1\r\nHo", raw_request(server, "POST", "/api/state", token=server.token,
                                                                   length="10")):
            with socket.create_connection(("127.0.0.1", server.server_address[1]), timeout=20) as sock:
                sock.sendall(data)
                assert sock.makefile("rb").read() == b"", "the server closes a connection whose request stalls"
        with socket.create_connection(("127.0.0.1", server.server_address[1]), timeout=20) as sock:
            sock.sendall(raw_request(server, "GET", "/api/state", token=server.token))
            reader = sock.makefile("rb")
            assert reader.readline().startswith(b"HTTP/1.1 200")
            reader.read()  # then idle on the kept-alive connection: closed too (read returns at the close)


def test_connections_beyond_the_cap_get_503(studio):
    with serving(StudioServer(studio, max_connections=2)) as server:
        address = ("127.0.0.1", server.server_address[1])
        holders = [socket.create_connection(address, timeout=20) for _ in range(2)]
        try:
            with socket.create_connection(address, timeout=20) as extra:
                reply = extra.makefile("rb").read()
            assert reply.startswith(b"HTTP/1.1 503 ") and b"X-Frame-Options: DENY" in reply
        finally:
            for holder in holders:
                holder.close()
        deadline = time.monotonic() + 20  # the holders' threads end when they see the close: then served again
        while (status := responses(exchange(server, raw_request(server, "GET", "/")))[0][0]) == 503:
            assert time.monotonic() < deadline, "a freed connection slot was never reused"
        assert status == 200


def test_a_client_that_resets_is_no_traceback(studio, capfd):
    with serving(StudioServer(studio, max_connections=1)) as server:
        with socket.create_connection(("127.0.0.1", server.server_address[1]), timeout=20) as sock:
            sock.sendall(b"GET / HTTP/1.1\r\nHo")
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))  # close = reset
        deadline = time.monotonic() + 20  # its one slot is free again once the reset was handled
        while (status := responses(exchange(server, raw_request(server, "GET", "/")))[0][0]) == 503:
            assert time.monotonic() < deadline, "the reset connection was never let go"
        assert status == 200
    assert "Traceback" not in capfd.readouterr().err


def test_a_burst_of_connections_waits_in_the_backlog(studio):
    server = StudioServer(studio, max_connections=100)
    address = ("127.0.0.1", server.server_address[1])
    waiting = []
    try:
        for _ in range(100):  # the server does not accept yet: every connection must fit the listen backlog
            waiting.append(socket.create_connection(address, timeout=5))
        with serving(server):
            for sock in waiting:
                sock.sendall(raw_request(server, "GET", "/static/studio.css", extra=("Connection: close",)))
            for sock in waiting:
                assert sock.makefile("rb").read().startswith(b"HTTP/1.1 200 ")
    finally:
        for sock in waiting:
            sock.close()
        server.server_close()


def test_parallel_saves_of_a_new_file_do_not_replace_each_other(studio, hexagon, folder):
    for round_ in range(3):
        barrier = threading.Barrier(6)
        answers: list[tuple[int, dict]] = []

        def save_one(name: int) -> None:
            job = copy.deepcopy(hexagon)
            job["design"]["name"] = f"writer-{name}"
            barrier.wait(timeout=20)
            answers.append(call(studio, "/api/save", {"job": job, "target": f"race-{round_}.toml"}))

        threads = [threading.Thread(target=save_one, args=(n,)) for n in range(6)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join(timeout=60)
        assert sorted(status for status, _ in answers) == [200] + [409] * 5
        winner = next(answer for status, answer in answers if status == 200)
        assert load_job(folder / f"race-{round_}.toml").name == winner["job"]["design"]["name"]
        assert all(answer["exists"] for status, answer in answers if status == 409)


def test_the_path_field_cannot_widen_the_relative_rule(tmp_path, hexagon):
    start = tmp_path / "a" / "work"
    start.mkdir(parents=True)
    studio = Studio(start, start / "job.toml")
    for target in ("../pwned.toml", "../../pwned.toml"):
        status, answer = call(studio, "/api/save", {"job": hexagon, "path": str(tmp_path / "a" / "x.toml"),
                                                    "target": target})
        assert status == 400 and "must stay inside" in answer["error"]
    assert not list(tmp_path.rglob("pwned.toml"))
    status, _ = call(studio, "/api/save", {"job": hexagon, "path": str(tmp_path / "a" / "x.toml"), "target": "ok.toml"})
    assert status == 200 and (start / "ok.toml").is_file(), "relative targets start in the studio's folder"


def test_cli_starts_the_server(tmp_path):
    import subprocess
    import sys
    import urllib.request

    shutil.copy(JOB_FOLDER / "hexagon-fig8a.toml", tmp_path / "h.toml")
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
