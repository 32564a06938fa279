"""Reading the files a user names: regular files only, and never more than a limit.

Every path that comes from outside (job files, SVG inputs, device profiles, resume
states, the studio's open field) is read by :func:`read_text`.  A FIFO, a device such as
``/dev/zero`` or a folder is refused before anything is read: the file is opened with
``O_NONBLOCK``, so opening a FIFO with no writer returns at once instead of waiting for
one, and the kind of file is then taken from the open descriptor (no race with a rename).
At most ``limit + 1`` bytes are read, so a file that grows while it is read is still
refused, never read whole.
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

from foldfab.errors import FoldfabError

JOB_LIMIT = 64 * 2**20
"""Bytes: the largest job file read (a profile of a million points written out is ~40 MB)."""
SVG_LIMIT = 64 * 2**20
"""Bytes: the largest SVG input read."""
SMALL_LIMIT = 2**20
"""Bytes: the largest device profile or resume state read (they are a few kilobytes)."""

_KINDS = ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


class MissingFile(FoldfabError, FileNotFoundError):
    """The named file does not exist (a caller may say more: catch ``FileNotFoundError``)."""


def read_bytes(path: str | os.PathLike, what: str, limit: int, follow_links: bool = True) -> bytes:
    """The bytes of the regular file ``path`` (a ``what``: "job file", "SVG file"...), at most ``limit``.

    Raises :class:`FoldfabError` naming the path for a missing or unreadable file, a file that
    is not a regular file (or, unless ``follow_links``, a symbolic link), and a file larger
    than ``limit`` bytes.
    """
    path = Path(path)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags if follow_links else flags | getattr(os, "O_NOFOLLOW", 0))
    except FileNotFoundError:
        raise MissingFile(f"{path}: {what} not found") from None
    except OSError as exc:
        if exc.errno == errno.ELOOP and not follow_links:
            raise FoldfabError(f"{path}: is a symbolic link, not a {what}; foldfab reads its {what}s only "
                               "where it wrote them") from None
        raise FoldfabError(f"{path}: cannot read the {what} ({exc.strerror or exc})") from None
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            kind = next((name for test, name in _KINDS if test(mode)), "not a regular file")
            raise FoldfabError(f"{path}: is {kind}, not a {what}; give the path of a regular file")
        if os.fstat(fd).st_size > limit:
            raise _too_large(path, what, limit)
        chunks, size = [], 0
        try:
            while size <= limit:
                chunk = os.read(fd, min(limit + 1 - size, 2**20))
                if not chunk:
                    break
                chunks.append(chunk)
                size += len(chunk)
        except OSError as exc:
            raise FoldfabError(f"{path}: cannot read the {what} ({exc.strerror or exc})") from None
        if size > limit:
            raise _too_large(path, what, limit)
        return b"".join(chunks)
    finally:
        os.close(fd)


def read_text(path: str | os.PathLike, what: str, limit: int, encoding: str = "utf-8-sig",
              follow_links: bool = True) -> str:
    """:func:`read_bytes` decoded (by default UTF-8, a byte-order mark allowed: some Windows
    editors write one); text that is not UTF-8 is a :class:`FoldfabError` naming the byte."""
    data = read_bytes(path, what, limit, follow_links)
    try:
        return data.decode(encoding)
    except UnicodeDecodeError as exc:
        raise FoldfabError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start}); "
                           f"save the {what} as UTF-8") from None


def _too_large(path: Path, what: str, limit: int) -> FoldfabError:
    size = f"{limit // 2**20} MB" if limit % 2**20 == 0 else f"{limit} bytes"
    return FoldfabError(f"{path}: larger than {size}, the most foldfab reads of a {what}; "
                        f"is it the right file?")
