"""A real PostgreSQL server for the tests: ``initdb`` into a fresh folder, ``pg_ctl start`` on a
Unix socket in it (no TCP port), as an unprivileged user, stopped at the end.

PostgreSQL refuses to run as root: under root the server runs as ``nobody`` and the folder is
given to that user; otherwise as the user running the tests.  The binaries are Debian's
(``/usr/lib/postgresql/<version>/bin``, the newest version), found at run time;
``$FOLDFAB_PG_BIN`` names another folder.  Nothing here sleeps: ``pg_ctl start -w`` returns once
the server accepts connections, and :meth:`PostgresServer.start` then checks with ``pg_isready``.
"""

from __future__ import annotations

import os
import pwd
import re
import shutil
import subprocess
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

SUPERUSER = "foldfab"
"""The database superuser ``initdb`` creates (local connections are trusted: the socket's folder
is readable only by the server's user and root)."""


def bin_folder() -> Path:
    """The folder of ``initdb`` and ``pg_ctl``: $FOLDFAB_PG_BIN, else Debian's newest version."""
    if os.environ.get("FOLDFAB_PG_BIN"):
        return Path(os.environ["FOLDFAB_PG_BIN"])
    versions = sorted(Path("/usr/lib/postgresql").glob("*/bin/initdb"),
                      key=lambda p: [int(n) for n in re.findall(r"\d+", p.parent.parent.name)])
    if not versions:
        raise RuntimeError("PostgreSQL's server binaries are not installed (no /usr/lib/postgresql/*/bin/initdb): "
                           "apt-get install postgresql, or set FOLDFAB_PG_BIN (scripts/test installs it)")
    return versions[-1].parent


def _server_user() -> pwd.struct_passwd:
    """Who runs the server: this user, or ``nobody`` when the tests run as root."""
    return pwd.getpwnam("nobody") if os.geteuid() == 0 else pwd.getpwuid(os.geteuid())


class PostgresServer:
    """One throw-away cluster.  :attr:`socket_dir` holds its socket; :meth:`url` names a database."""

    def __init__(self) -> None:
        self.bin = bin_folder()
        self.user = _server_user()
        self.folder = Path(tempfile.mkdtemp(prefix="foldfab-pg-"))
        self.data = self.folder / "data"
        self.socket_dir = self.folder
        self.log = self.folder / "server.log"
        self.databases = 0
        os.chown(self.folder, self.user.pw_uid, self.user.pw_gid)

    def _run(self, *command: str, check: bool = True) -> subprocess.CompletedProcess:
        """A PostgreSQL program, as the server's user."""
        as_user = {} if os.geteuid() != 0 else {"user": self.user.pw_uid, "group": self.user.pw_gid,
                                                 "extra_groups": []}
        return subprocess.run([str(self.bin / command[0]), *command[1:]], capture_output=True, text=True,
                              check=check, timeout=120, cwd=self.folder, env={"PATH": os.environ.get("PATH", ""),
                                                                              "LANG": "C.UTF-8"}, **as_user)

    def start(self) -> "PostgresServer":
        if not self.data.exists():
            self._run("initdb", "-D", str(self.data), "-U", SUPERUSER, "--auth=trust", "-E", "UTF8", "--no-sync")
        self._pg_ctl("start")
        return self._ready()

    def restart(self, mode: str = "fast") -> None:
        """``pg_ctl restart``: the server stops (``mode``), cutting every connection, and starts again."""
        self._pg_ctl("restart", "-m", mode)
        self._ready()

    def _pg_ctl(self, action: str, *args: str) -> None:
        options = f"-k {self.socket_dir} -c listen_addresses='' -c fsync=off -c max_connections=200"
        result = self._run("pg_ctl", action, *args, "-w", "-t", "120", "-D", str(self.data), "-l", str(self.log),
                           "-o", options, check=False)
        if result.returncode != 0:
            raise RuntimeError(f"pg_ctl {action} failed: {result.stderr}\n{self.log.read_text()}")

    def _ready(self) -> "PostgresServer":
        ready = self._run("pg_isready", "-h", str(self.socket_dir), "-U", SUPERUSER, "-d", "postgres", check=False)
        if ready.returncode != 0:
            raise RuntimeError(f"the server does not accept connections: {ready.stdout}")
        return self

    def stop(self, mode: str = "fast") -> None:
        """Stop the server (``mode``: fast, or immediate as a power cut would)."""
        if (self.data / "postmaster.pid").exists():
            self._run("pg_ctl", "stop", "-w", "-t", "120", "-m", mode, "-D", str(self.data), check=False)

    def destroy(self) -> None:
        self.stop()
        shutil.rmtree(self.folder, ignore_errors=True)

    def url(self, database: str = "postgres") -> str:
        """A libpq URL for ``database`` through the socket."""
        return f"postgresql://{SUPERUSER}@/{database}?host={self.socket_dir}"

    def new_database(self) -> str:
        """A fresh, empty database; its URL."""
        self.databases += 1
        name = f"test{self.databases}"
        self._run("createdb", "-h", str(self.socket_dir), "-U", SUPERUSER, name)
        return self.url(name)


@contextmanager
def running_server() -> Iterator[PostgresServer]:
    """A started server, stopped and deleted at the end."""
    server = PostgresServer()
    try:
        yield server.start()
    finally:
        server.destroy()
