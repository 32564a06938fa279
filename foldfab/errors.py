"""The one exception type a user's mistake raises.

Library code raises :class:`FoldfabError` with a message that names the file,
the key or the line, what was expected and what to do.  The command line turns
it into a one-line message and exit code 2, never a traceback.
"""

from __future__ import annotations


class FoldfabError(Exception):
    """A user-facing error: bad job file, invalid design, unusable device..."""

    exit_code = 2


class DesignError(FoldfabError):
    """The design is geometrically invalid (odd corners, negative lengths, penetration)."""
