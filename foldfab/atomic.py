"""Atomic file output: a file, or a set of files, is either written whole or not at all.

Each file goes to a temporary file beside its target first and is renamed into place
only when every file of the set is complete, so a failure leaves every target as it
was.  A symbolic link is written through (the file it points to is replaced, the link
stays); an existing target that is not a regular file (``/dev/stdout``, a FIFO) is
written in place, since renaming over it would replace the device itself.
"""

from __future__ import annotations

import os
import stat
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


class _Staged:
    """One file of a set: its data written, as it comes, to a temporary file beside the target,
    or held for a target that is written in place."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.given = path
        self.path = Path(path)
        self.held: list[bytes] = []
        self.handle = None
        self.tmp: str | None = None
        try:
            mode = os.stat(self.path).st_mode  # through a symbolic link
        except FileNotFoundError:
            mode = None
        if mode is not None and stat.S_ISDIR(mode):
            raise IsADirectoryError(21, "Is a directory", str(self.path))
        if mode is not None and not stat.S_ISREG(mode):
            return  # a device or FIFO: written in place by commit()
        self.path = Path(os.path.realpath(self.path)) if self.path.is_symlink() else self.path
        directory = self.path.parent if str(self.path.parent) else Path(".")
        fd, self.tmp = tempfile.mkstemp(prefix=f".{self.path.name}.", suffix=".part", dir=directory)
        try:
            os.chmod(self.tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the file a new file's usual mode
            self.handle = os.fdopen(fd, "wb")
        except BaseException:
            os.close(fd)
            self.discard()
            raise

    def write(self, data: bytes) -> None:
        """Append ``data`` (to the temporary file, or held for an in-place target)."""
        if self.handle is None:
            self.held.append(bytes(data))
        else:
            with _naming(self.given):
                self.handle.write(data)

    def read(self) -> bytes:
        """Everything written so far (read back from the temporary file)."""
        if self.handle is None:
            return b"".join(self.held)
        self.handle.flush()
        with open(self.tmp, "rb") as handle:
            return handle.read()

    def finish(self) -> None:
        """Flush the temporary file to the disk (before any file of the set is renamed)."""
        if self.handle is not None:
            self.handle.flush()
            os.fsync(self.handle.fileno())
            self.handle.close()
            self.handle = None

    def commit(self) -> None:
        if self.tmp is None:
            with open(self.path, "wb") as handle:
                handle.write(b"".join(self.held))
        else:
            os.replace(self.tmp, self.path)
            self.tmp = None

    def discard(self) -> None:
        if self.handle is not None:
            self.handle.close()
            self.handle = None
        if self.tmp is not None:
            try:
                os.unlink(self.tmp)
            except FileNotFoundError:
                pass
            self.tmp = None


def write_files(files: Sequence[tuple[str | os.PathLike, bytes]]) -> None:
    """Write every ``(path, data)`` whole, or none of them.

    An ``OSError`` names the path that failed, as given, in its ``filename``; every
    target is then as it was, unless a rename itself failed after all the data was
    written (the one step that cannot be undone: the targets renamed before it stay
    replaced).
    """
    with stream_files([path for path, _ in files]) as staged:
        for item, (_, data) in zip(staged, files):
            item.write(data)


@contextmanager
def stream_files(paths: Sequence[str | os.PathLike]) -> Iterator[list[_Staged]]:
    """Files written piece by piece, each whole or none of them: ``with stream_files(paths) as
    files:`` gives one writer per path (``files[i].write(data)``, and ``files[i].read()`` for
    what it holds so far); they replace their targets only when the block ends without an
    exception, and an exception (Ctrl-C included) leaves every target as it was and no
    temporary file.  ``OSError`` as for :func:`write_files`."""
    staged: list[_Staged] = []
    try:
        for path in paths:
            with _naming(path):
                staged.append(_Staged(path))
        yield staged
        for item in staged:
            with _naming(item.given):
                item.finish()
        for item in sorted(staged, key=lambda item: item.tmp is not None):  # in place first: they may fail
            with _naming(item.given):
                item.commit()
    finally:
        for item in staged:
            item.discard()


@contextmanager
def _naming(path: str | os.PathLike) -> Iterator[None]:
    """An ``OSError`` inside names ``path`` as given."""
    try:
        yield
    except OSError as exc:
        raise OSError(exc.errno, exc.strerror or str(exc), os.fspath(path)) from exc


def write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``path`` atomically (UTF-8, ``\\n`` line endings as given)."""
    write_files([(path, text.encode("utf-8"))])


def write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    write_files([(path, data)])
