"""The studio's web server: the page, its static files and the API, on 127.0.0.1 only.

Who may talk to it: the page it hands out, in a browser on this machine.  Each request
must name this server in exactly one ``Host`` header (no DNS rebinding); each API request
carries the session's token in ``X-Foldfab-Token`` (written into the page, never in a URL);
a ``POST`` must come from the studio's own ``Origin`` (and ``Sec-Fetch-Site: same-origin``
where the browser sends it), so another web site can neither call the API nor frame the page.

How it reads HTTP: ``http.server`` (stdlib), made strict.  Framing is checked before
anything else (one decimal ``Content-Length``, no ``Transfer-Encoding``, no body on ``GET``,
no malformed or folded header lines), and every response that does not consume the
request's body closes the connection, so a refused request's body is never read as a
next request.  Each request must arrive whole within :attr:`StudioServer.request_timeout`
(idle keep-alive connections included), at most :attr:`StudioServer.max_connections`
are served at once (more get a 503), and the listen backlog is 128.
Static files come from the package (``static/``, three.js vendored): nothing is
loaded from the internet.
"""

from __future__ import annotations

import io
import json
import mimetypes
import re
import secrets
import socket
import sys
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Callable

from foldfab.studio.api import MAX_BODY, Studio

STATIC = Path(__file__).resolve().parent / "static"
TYPES = {".js": "text/javascript; charset=utf-8", ".css": "text/css; charset=utf-8",
         ".html": "text/html; charset=utf-8", ".txt": "text/plain; charset=utf-8", ".svg": "image/svg+xml",
         ".md": "text/plain; charset=utf-8"}
_STATIC_NAME = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9_.-]*(/[A-Za-z0-9_-][A-Za-z0-9_.-]*)*")


class StudioServer(ThreadingHTTPServer):
    """An HTTP server for one :class:`Studio` session."""

    daemon_threads = True
    request_queue_size = 128  # the listen backlog: a burst of parallel requests waits instead of being reset

    def __init__(self, studio: Studio, port: int = 0, quiet: bool = True, request_timeout: float = 20.0,
                 max_connections: int = 32):
        self.studio = studio
        self.token = secrets.token_urlsafe(24)
        self.quiet = quiet
        self.request_timeout = request_timeout
        self.max_connections = max_connections
        self._slots = threading.BoundedSemaphore(max_connections)
        super().__init__(("127.0.0.1", port), Handler)

    @property
    def url(self) -> str:
        """The page's address."""
        return f"http://127.0.0.1:{self.server_address[1]}/"

    def allowed_hosts(self) -> set[str]:
        """The ``Host`` values that name this server."""
        port = self.server_address[1]
        return {f"127.0.0.1:{port}", f"localhost:{port}"}

    def allowed_origins(self) -> set[str]:
        """The ``Origin`` values of the studio's own page."""
        return {f"http://{host}" for host in self.allowed_hosts()}

    def process_request(self, request, client_address) -> None:
        """Serve the connection in a thread, or answer 503 when :attr:`max_connections` are busy."""
        if not self._slots.acquire(blocking=False):
            try:
                request.settimeout(1.0)
                request.sendall(_BUSY)
            except OSError:
                pass
            self.shutdown_request(request)
            return
        try:
            super().process_request(request, client_address)
        except BaseException:
            self._slots.release()
            raise

    def process_request_thread(self, request, client_address) -> None:
        try:
            super().process_request_thread(request, client_address)
        finally:
            self._slots.release()

    def handle_error(self, request, client_address) -> None:
        """A client that went away (reset, broken pipe, timeout) is no error worth a traceback."""
        if not isinstance(sys.exc_info()[1], OSError):
            super().handle_error(request, client_address)


SECURITY_HEADERS = (("X-Frame-Options", "DENY"), ("Content-Security-Policy", "frame-ancestors 'none'"),
                    ("X-Content-Type-Options", "nosniff"), ("Referrer-Policy", "no-referrer"),
                    ("Cache-Control", "no-store"))
_BUSY_TEXT = b"foldfab studio: too many connections at once; try again\n"
_BUSY = (b"HTTP/1.1 503 Service Unavailable\r\nContent-Type: text/plain\r\nConnection: close\r\nRetry-After: 1\r\n"
         + b"".join(f"{name}: {value}\r\n".encode() for name, value in SECURITY_HEADERS)
         + f"Content-Length: {len(_BUSY_TEXT)}\r\n\r\n".encode() + _BUSY_TEXT)
_TOKEN_CHARS = re.compile(r"[!#$%&'*+.^_`|~0-9A-Za-z-]+")  # RFC 9110 token: a header name
_LENGTH = re.compile(r"[0-9]{1,12}")
_LINGER_SECONDS, _LINGER_BYTES = 1.0, MAX_BODY + 2**16


class _DeadlineReader(io.RawIOBase):
    """The socket's input, each read bounded by the current request's deadline (slow clients time out)."""

    def __init__(self, sock: socket.socket):
        self.sock = sock
        self.deadline = float("inf")

    def readable(self) -> bool:
        return True

    def readinto(self, buffer) -> int:
        left = self.deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError("the request did not arrive in time")
        self.sock.settimeout(left)
        return self.sock.recv_into(buffer)


class Refused(Exception):
    """A request the server answers with ``status`` and ``message`` and then closes the connection."""

    def __init__(self, status: int, message: str):
        super().__init__(message)
        self.status = status


class Handler(BaseHTTPRequestHandler):
    """Serves ``/`` (the page), ``/static/...`` and ``/api/...``."""

    server: StudioServer
    server_version = "foldfab-studio"
    protocol_version = "HTTP/1.1"
    default_request_version = "HTTP/1.1"  # a malformed request line is answered with headers too (never HTTP/0.9)

    def setup(self) -> None:
        super().setup()
        self._reader = _DeadlineReader(self.connection)
        self.rfile = io.BufferedReader(self._reader, 65536)
        self._status, self._close_said = 0, False
        self._length: int | None = None
        self._body_read = True

    def handle_one_request(self) -> None:
        self._reader.deadline = time.monotonic() + self.server.request_timeout
        self._length, self._body_read = None, True
        super().handle_one_request()

    def handle(self) -> None:
        super().handle()
        self._linger()

    def _linger(self) -> None:
        """Close without reading the rest as a request: stop sending, then discard what the client still
        sends (bounded in time and bytes), so it reads a refusal instead of a connection reset."""
        try:
            self.wfile.flush()
            self.connection.shutdown(socket.SHUT_WR)
            end, left = time.monotonic() + _LINGER_SECONDS, _LINGER_BYTES
            while left > 0 and (wait := end - time.monotonic()) > 0:
                self.connection.settimeout(wait)
                data = self.connection.recv(min(left, 65536))
                if not data:
                    break
                left -= len(data)
        except OSError:
            pass

    # -- the checks, before anything is served

    def _framing(self) -> None:
        """The request's body length from one plain ``Content-Length``; malformed requests are refused."""
        if self.headers.defects or self.headers.get_payload():
            raise Refused(400, "malformed header line")
        for name, value in self.headers.items():
            if not _TOKEN_CHARS.fullmatch(name) or "\r" in value or "\n" in value:
                raise Refused(400, "malformed header line")
        if "Transfer-Encoding" in self.headers:
            raise Refused(501, "Transfer-Encoding is not supported: send Content-Length")
        lengths = self.headers.get_all("Content-Length") or []
        if len(lengths) > 1:
            raise Refused(400, "more than one Content-Length")
        if lengths:
            if not _LENGTH.fullmatch(lengths[0].strip(" \t")):
                raise Refused(400, "Content-Length must be a decimal number")
            self._length = int(lengths[0])
            self._body_read = self._length == 0

    def _guard(self, method: str) -> str:
        """The request's path once it passes the Host, origin, token and framing checks."""
        self._framing()
        hosts = self.headers.get_all("Host") or []
        if len(hosts) != 1:
            raise Refused(400, "exactly one Host header is required")
        if hosts[0] not in self.server.allowed_hosts():
            raise Refused(403, "foldfab studio answers only at 127.0.0.1 or localhost")
        if not self.path.startswith("/") or self.path.startswith("//"):
            raise Refused(400, "request target must be a path")
        path = self.path.split("?", 1)[0].split("#", 1)[0]
        if method == "GET" and self._length:
            raise Refused(400, "a GET request has no body")
        if not path.startswith("/api/"):
            if method != "GET":
                raise Refused(405, "method not allowed")
            return path
        token = self.headers.get("X-Foldfab-Token", "").encode("latin-1", "replace")
        if not secrets.compare_digest(token, self.server.token.encode()):
            raise Refused(403, "missing or wrong studio token: reload the page")
        origin, site = self.headers.get_all("Origin") or [], self.headers.get_all("Sec-Fetch-Site") or []
        if (method == "POST" and not origin) or any(o not in self.server.allowed_origins() for o in origin) \
                or len(origin) > 1 or any(s != "same-origin" for s in site):
            raise Refused(403, "requests to the studio's API must come from the studio's own page")
        if method == "POST":
            if self.headers.get_content_type() != "application/json":
                raise Refused(415, "send JSON (Content-Type: application/json)")
            if self._length is None:
                raise Refused(411, "Content-Length required")
            if self._length > MAX_BODY:
                raise Refused(413, f"request too large ({self._length} bytes; at most {MAX_BODY})")
        return path

    def handle_expect_100(self) -> bool:
        """Answer ``Expect: 100-continue`` only for a request that passes the checks."""
        try:
            self._guard(self.command)
        except Refused as refused:
            self._refuse(refused)
            return False
        return super().handle_expect_100()

    # -- serving

    def do_GET(self) -> None:  # noqa: N802 (http.server's naming)
        self._serve("GET")

    def do_POST(self) -> None:  # noqa: N802
        self._serve("POST")

    def _serve(self, method: str) -> None:
        try:
            path = self._guard(method)
        except Refused as refused:
            return self._refuse(refused)
        if path.startswith("/api/"):
            return self._api(method, path)
        if path in ("/", "/index.html"):
            page = (STATIC / "index.html").read_text(encoding="utf-8").replace("{{TOKEN}}", self.server.token)
            return self._send(200, TYPES[".html"], page.encode())
        if path.startswith("/static/"):
            return self._static(path.removeprefix("/static/"))
        self._send(404, "text/plain", b"not found\n")

    def _static(self, name: str) -> None:
        file = (STATIC / name).resolve()
        if not _STATIC_NAME.fullmatch(name) or not file.is_relative_to(STATIC) or not file.is_file():
            return self._send(404, "text/plain", b"not found\n")
        kind = TYPES.get(file.suffix) or mimetypes.guess_type(file.name)[0] or "application/octet-stream"
        self._send(200, kind, file.read_bytes())

    def _api(self, method: str, path: str) -> None:
        body = b""
        if method == "POST" and self._length:
            body = self.rfile.read(self._length)
            if len(body) < self._length:  # the client closed early
                self.close_connection = True
                return
            self._body_read = True
        response = self.server.studio.handle(method, path, body)
        self._send(response.status, response.content_type, response.body)

    def _refuse(self, refused: Refused) -> None:
        """Answer ``refused`` and close: the body (if any) is never read as a request."""
        self.close_connection = True
        if self.path.startswith("/api/"):
            self._send(refused.status, "application/json", json.dumps({"error": str(refused)}).encode())
        else:
            self._send(refused.status, "text/plain", f"{refused}\n".encode())

    def send_response_only(self, code: int, message: str | None = None) -> None:
        self._status, self._close_said = code, False
        super().send_response_only(code, message)

    def send_header(self, keyword: str, value: str) -> None:
        if keyword.lower() == "connection" and value.lower() == "close":
            self._close_said = True
        super().send_header(keyword, value)

    def end_headers(self) -> None:
        """Every final response: the security headers, and ``Connection: close`` when the body is unread."""
        if self._status >= 200:
            for name, value in SECURITY_HEADERS:
                self.send_header(name, value)
            if not self._body_read:
                self.close_connection = True
            if self.close_connection and not self._close_said:
                self.send_header("Connection", "close")
            self.connection.settimeout(self.server.request_timeout)  # a client that does not read times out too
        super().end_headers()

    def _send(self, status: int, content_type: str, body: bytes) -> None:
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        try:
            self.wfile.write(body)
        except (BrokenPipeError, ConnectionResetError):  # the page went away (reload, closed tab)
            self.close_connection = True

    def log_message(self, format: str, *args) -> None:  # noqa: A002 (http.server's signature)
        if not self.server.quiet:
            super().log_message(format, *args)


def serve(studio: Studio, port: int = 0, open_browser: bool = True, announce: Callable[[str], None] = print) -> None:
    """Serve ``studio`` until interrupted; announce the URL and open a browser on it."""
    import webbrowser

    try:
        server = StudioServer(studio, port)
    except OSError as exc:
        from foldfab.errors import FoldfabError

        raise FoldfabError(f"cannot listen on 127.0.0.1:{port}: {exc.strerror or exc}; "
                           "choose another --port (0 picks a free one)") from None
    announce(server.url)
    if open_browser and not webbrowser.open(server.url):
        print("foldfab: no web browser found; open the address above yourself", file=sys.stderr)
    try:
        server.serve_forever(poll_interval=0.2)
    finally:
        server.server_close()
