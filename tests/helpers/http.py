"""The studio's HTTP server in a thread, and raw HTTP/1.1 exchanges with it (framing, smuggling)."""

from __future__ import annotations

import contextlib
import json
import socket
import threading

from foldfab.studio.server import StudioServer


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


def exchange(server: StudioServer, data: bytes, timeout: float = 20.0) -> bytes:
    """Send ``data`` on one connection, stop sending, and read until the server closes."""
    with socket.create_connection(("127.0.0.1", server.server_address[1]), timeout=timeout) as sock:
        try:
            sock.sendall(data)
            sock.shutdown(socket.SHUT_WR)
        except OSError:  # the server closed first (a refusal): read what it answered
            pass
        chunks = []
        with contextlib.suppress(ConnectionResetError):
            while chunk := sock.recv(65536):
                chunks.append(chunk)
    return b"".join(chunks)


def responses(data: bytes) -> list[tuple[int, dict[str, list[str]], bytes]]:
    """The HTTP responses in ``data``: (status, headers by lower-case name, body), framed by Content-Length."""
    found = []
    while data:
        head, separator, rest = data.partition(b"\r\n\r\n")
        assert separator, f"a response without the end of its headers: {data[:200]!r}"
        lines = head.decode("latin-1").split("\r\n")
        version, status = lines[0].split(" ")[:2]
        assert version == "HTTP/1.1", lines[0]
        headers: dict[str, list[str]] = {}
        for line in lines[1:]:
            name, _, value = line.partition(":")
            headers.setdefault(name.strip().lower(), []).append(value.strip())
        length = int(headers["content-length"][0])
        found.append((int(status), headers, rest[:length]))
        data = rest[length:]
    return found


def raw_request(server: StudioServer, method: str = "GET", target: str = "/", body: bytes = b"",
                host: str | None = None, token: str | None = None, origin: str | None = "own",
                content_type: str | None = "application/json", length: str | None = "auto",
                extra: tuple[str, ...] = ()) -> bytes:
    """One request as bytes, each part given (``None`` leaves it out; ``origin="own"``, ``length="auto"``)."""
    own = f"127.0.0.1:{server.server_address[1]}"
    lines = [f"{method} {target} HTTP/1.1", f"Host: {host or own}"]
    if token is not None:
        lines.append(f"X-Foldfab-Token: {token}")
    if origin is not None:
        lines.append(f"Origin: {'http://' + own if origin == 'own' else origin}")
    if content_type is not None and method == "POST":
        lines.append(f"Content-Type: {content_type}")
    if length is not None and (body or method == "POST"):
        lines.append(f"Content-Length: {len(body) if length == 'auto' else length}")
    lines.extend(extra)
    return ("\r\n".join(lines) + "\r\n\r\n").encode("latin-1") + body


def smuggled(server: StudioServer, hexagon: dict, name: str = "smuggled.toml") -> bytes:
    """Two valid requests: the page (it carries the token) and a save of ``name``."""
    save = json.dumps({"job": hexagon, "target": name}).encode()
    return raw_request(server, "GET", "/") + raw_request(server, "POST", "/api/save", save, token=server.token)


def refusals(server: StudioServer, inner: bytes) -> dict[str, tuple[bytes, int]]:
    """Requests the studio refuses, each carrying ``inner`` as its body or after it; the status expected."""
    token = server.token
    return {
        "host": (raw_request(server, "POST", "/api/save", inner, host="evil.example", token=token), 403),
        "token": (raw_request(server, "POST", "/api/save", inner, token="guess"), 403),
        "method": (raw_request(server, "POST", "/", inner, token=token), 405),
        "content type": (raw_request(server, "POST", "/api/save", inner, token=token, content_type="text/plain"), 415),
        "no length": (raw_request(server, "POST", "/api/save", token=token, length=None) + inner, 411),
        "chunked": (raw_request(server, "POST", "/api/save", token=token, length=None,
                                extra=("Transfer-Encoding: chunked",)) + f"{len(inner):x}\r\n".encode() + inner
                    + b"\r\n0\r\n\r\n", 501),
        "two lengths": (raw_request(server, "POST", "/api/save", inner, token=token,
                                    extra=(f"Content-Length: {len(inner)}",)), 400),
        "junk length": (raw_request(server, "POST", "/api/save", inner, token=token, length=f"+{len(inner)}"), 400),
        "body on GET": (raw_request(server, "GET", "/api/state", inner, token=token), 400),
        "two hosts": (raw_request(server, "GET", "/", extra=("Host: evil.example",)) + inner, 400),
        "foreign origin": (raw_request(server, "POST", "/api/save", inner, token=token,
                                       origin="http://evil.example"), 403),
    }
