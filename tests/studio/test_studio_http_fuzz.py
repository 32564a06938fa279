"""A fuzz test of the studio's HTTP parsing, over a raw socket against a real StudioServer on 127.0.0.1.

Each case is one connection: pipelined valid requests, then one request the studio must refuse
(a refusal of every kind, a refused request with random bytes changed, or random bytes), each
refused one carrying a complete smuggled request (the page, which holds the token, and a save)
as its body or after it.  The valid requests before it must be answered 200 in order, the
refused one with one refusal and a close, and nothing after it: the smuggled page is never
served and the smuggled file never written.  Seeded (the seed is in every failure message),
bounded in count and in time.
"""

from __future__ import annotations

import json
import random
import time

from foldfab.job import job_data, load_job
from foldfab.studio.api import Studio
from foldfab.studio.server import StudioServer
from helpers import JOB_FOLDER
from helpers.http import exchange, raw_request, refusals, responses, serving, smuggled

SEED = 1717
CASES = 300
SECONDS = 60.0
SMUGGLED = "smuggled.toml"


def valid_requests(server: StudioServer) -> list[bytes]:
    """Requests the studio answers 200 and keeps the connection open."""
    return [raw_request(server, "GET", "/api/state", token=server.token),
            raw_request(server, "POST", "/api/files", b"{}", token=server.token),
            raw_request(server, "GET", "/static/studio.css")]


def mutate(data: bytes, rng: random.Random) -> bytes:
    """``data`` with one or two bytes replaced, inserted or deleted (the foreign Host is left as it is)."""
    keep = data.index(b"evil.example")
    for _ in range(rng.randint(1, 2)):
        at = rng.randrange(len(data))
        if keep <= at < keep + len(b"evil.example"):
            continue
        byte = bytes([rng.choice([rng.randrange(256), *b"\r\n :0123456789"])])
        edit = rng.choice(("replace", "insert", "delete"))
        data = data[:at] + (byte if edit != "delete" else b"") + data[at + (edit != "insert"):]
        keep = data.find(b"evil.example")
    return data


def refused_case(server: StudioServer, inner: bytes, rng: random.Random) -> tuple[str, bytes, int | None]:
    """(what, bytes, expected status or None for any refusal) of one request the studio must refuse."""
    kinds = refusals(server, inner)
    choice = rng.randrange(3)
    if choice == 0:
        kind = rng.choice(sorted(kinds))
        return kind, *kinds[kind]
    if choice == 1:
        foreign = {name: data for name, (data, _) in refusals(server, inner).items() if name not in ("host", "two hosts")}
        kind = rng.choice(sorted(foreign))
        data = foreign[kind].replace(f"Host: 127.0.0.1:{server.server_address[1]}".encode(), b"Host: evil.example", 1)
        return f"mutated {kind}", mutate(data, rng), None
    noise = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 300)))
    return "random bytes", rng.choice([b"", b"GET ", b"POST /api/save HTTP/1.1\r\n"]) + noise + inner, None


def test_fuzzed_requests_are_never_answered_when_they_should_be_refused(tmp_path):
    (tmp_path / "hexagon.toml").write_bytes((JOB_FOLDER / "hexagon-fig8a.toml").read_bytes())
    hexagon = job_data(load_job(tmp_path / "hexagon.toml"))
    rng = random.Random(SEED)
    with serving(StudioServer(Studio(tmp_path, tmp_path / "hexagon.toml"))) as server:
        valid, inner = valid_requests(server), smuggled(server, hexagon, SMUGGLED)
        token = server.token.encode()
        end, ran = time.monotonic() + SECONDS, 0
        while ran < CASES and time.monotonic() < end:
            before = [rng.choice(valid) for _ in range(rng.randrange(3))]
            what, bad, status = refused_case(server, inner, rng)
            after = [rng.choice(valid) for _ in range(rng.randrange(3))]
            where = f"case {ran} (seed {SEED}): {what}: {bad[:300]!r}"
            answered = responses(exchange(server, b"".join(before) + bad + b"".join(after)))
            statuses = [s for s, _, _ in answered]
            assert statuses[:len(before)] == [200] * len(before), where
            refusal = statuses[len(before):]
            if status is not None:
                assert refusal == [status], f"{where}: answered {statuses}"
            else:
                assert len(refusal) <= 1 and all(s >= 400 for s in refusal), f"{where}: answered {statuses}"
            if refusal:
                assert answered[-1][1].get("connection") == ["close"], where
            assert all(token not in body for _, _, body in answered), f"{where}: the page was served"
            assert not (tmp_path / SMUGGLED).exists(), f"{where}: the smuggled save was written"
            ran += 1
        assert ran >= 20, f"only {ran} cases in {SECONDS} s"
        state = raw_request(server, "GET", "/api/state", token=server.token)
        status, _, body = responses(exchange(server, state))[0]
        assert status == 200 and json.loads(body)["job"] == hexagon, "the server still answers after the fuzz"
