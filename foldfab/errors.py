"""The one exception type a user's mistake raises.

Library code raises :class:`FoldfabError` with a message that names the file,
the key or the line, what was expected and what to do.  The command line turns
it into a one-line message and exit code 2, never a traceback.
"""

from __future__ import annotations

from typing import Iterable


class FoldfabError(Exception):
    """A user-facing error: bad job file, invalid design, unusable device..."""

    exit_code = 2


class DesignError(FoldfabError):
    """The design is geometrically invalid (odd corners, negative lengths, penetration)."""


def unknown_key(given: Iterable[str], known: Iterable[str], form: str = "{}") -> tuple[str, str] | None:
    """The first of ``given`` (sorted) that is not ``known``, with a hint for its error message:
    the closest known key ("did you mean 'points'?") and the list of known keys, each written
    as ``form``.  None if all are known.  Every reader of keys (job tables, device
    profiles, simulator options) asks this before it reports a missing key, so a typo is named
    as a typo, not as the key it hides."""
    known = sorted(set(known))
    unknown = sorted(set(given) - set(known))
    if not unknown:
        return None
    import difflib  # only for a mistake: the command line's fast path stays lean

    key = unknown[0]
    match = difflib.get_close_matches(key, known, n=1, cutoff=0.6)
    hint = f"did you mean '{form.format(match[0])}'? " if match else ""
    return key, f"{hint}expected one of: {', '.join(map(form.format, known))}"
