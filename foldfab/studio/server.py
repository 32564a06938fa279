"""The studio's web server: the page, its static files and the API, on 127.0.0.1 only.

Every API request must carry the session's token (``X-Foldfab-Token``, written
into the page the server hands out) and a ``Host`` of this server, so another web
site open in the browser can neither call the API nor reach it by DNS rebinding.
Static files come from the package (``static/``, three.js vendored): nothing is
loaded from the internet.
"""

from __future__ import annotations

import mimetypes
import re
import secrets
import sys
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Callable
from urllib.parse import urlsplit

from foldfab.studio.api import MAX_BODY, Studio

STATIC = Path(__file__).resolve().parent / "static"
TYPES = {".js": "text/javascript; charset=utf-8", ".css": "text/css; charset=utf-8",
         ".html": "text/html; charset=utf-8", ".txt": "text/plain; charset=utf-8", ".svg": "image/svg+xml",
         ".md": "text/plain; charset=utf-8"}
_STATIC_NAME = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9_.-]*(/[A-Za-z0-9_-][A-Za-z0-9_.-]*)*")


class StudioServer(ThreadingHTTPServer):
    """An HTTP server for one :class:`Studio` session."""

    daemon_threads = True

    def __init__(self, studio: Studio, port: int = 0, quiet: bool = True):
        self.studio = studio
        self.token = secrets.token_urlsafe(24)
        self.quiet = quiet
        super().__init__(("127.0.0.1", port), Handler)

    @property
    def url(self) -> str:
        """The page's address."""
        return f"http://127.0.0.1:{self.server_address[1]}/"

    def allowed_hosts(self) -> set[str]:
        port = self.server_address[1]
        return {f"127.0.0.1:{port}", f"localhost:{port}"}


class Handler(BaseHTTPRequestHandler):
    """Serves ``/`` (the page), ``/static/...`` and ``/api/...``."""

    server: StudioServer
    server_version = "foldfab-studio"
    protocol_version = "HTTP/1.1"

    def do_GET(self) -> None:  # noqa: N802 (http.server's naming)
        self._serve("GET")

    def do_POST(self) -> None:  # noqa: N802
        self._serve("POST")

    def _serve(self, method: str) -> None:
        if self.headers.get("Host") not in self.server.allowed_hosts():
            return self._send(403, "text/plain", b"foldfab studio answers only at 127.0.0.1 or localhost\n")
        path = urlsplit(self.path).path
        if path.startswith("/api/"):
            return self._api(method, path)
        if method != "GET":
            return self._send(405, "text/plain", b"method not allowed\n")
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
        if not secrets.compare_digest(self.headers.get("X-Foldfab-Token", ""), self.server.token):
            return self._json_error(403, "missing or wrong studio token: reload the page")
        body = b""
        if method == "POST":
            if self.headers.get_content_type() != "application/json":
                return self._json_error(415, "send JSON (Content-Type: application/json)")
            try:
                length = int(self.headers.get("Content-Length", ""))
            except ValueError:
                return self._json_error(411, "Content-Length required")
            if length < 0 or length > MAX_BODY:
                self.close_connection = True
                return self._json_error(413, f"request too large ({length} bytes; at most {MAX_BODY})")
            body = self.rfile.read(length)
        response = self.server.studio.handle(method, path, body)
        self._send(response.status, response.content_type, response.body)

    def _json_error(self, status: int, message: str) -> None:
        import json

        self._send(status, "application/json", json.dumps({"error": message}).encode())

    def _send(self, status: int, content_type: str, body: bytes) -> None:
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("Referrer-Policy", "no-referrer")
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
