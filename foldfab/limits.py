"""The caps on what foldfab builds, checked before the work starts (the command line's
help names them, so this module imports nothing)."""

LENGTH_LIMIT = 1e6
"""Millimetres (a kilometre): no coordinate, radius or length of a job may be larger.  Past
it a design is no sheet of paper; and points are told apart to a billionth of the design's
size (``foldfab.geometry.reflection.REL_TOL``), so a larger trajectory blurs its profile's finer points
(a radius of 1e12 mm made points 1 mm apart "the same point")."""
MAX_FACES = 2_000_000
"""The most faces a design may have unless the job (``[design].max_faces``) or the command
line (``--max-faces``) allows more.  Twice the 1,000,000-face roll the benchmarks build.
``foldfab design --fold`` of 1,001,000 faces peaks at 0.9 GB (summary, penetration check and
FOLD file; 10 s of CPU), so the limit is about 1.8 GB: a 10-million-face design ran out of
memory after 6.5 GB and 48 s; refused, it costs a moment (the count is known from the
polylines alone)."""
MAX_STROKES = 2_000_000
"""The most strokes (lines drawn, each perforation dash one) a program may have unless the
job allows more (``[fabrication].max_strokes``).  The 1,000,000-face roll draws about a
million; a stroke costs a few hundred bytes on its way to the program (its line, its text,
its progress entry), so this is again about a gigabyte; a 0.1 mm perforation of a roll's
creases would otherwise run to tens of millions of dashes."""


MMAP_THRESHOLD = 1 << 20
"""Bytes from which glibc's malloc maps each block on its own, handed back to the system when
freed (:func:`release_large_blocks`)."""


def release_large_blocks() -> None:
    """Have glibc's malloc map every block of :data:`MMAP_THRESHOLD` bytes or more on its own,
    so that a large job's temporary arrays go back to the system once freed.

    By default glibc raises that threshold to the size of the largest block freed so far (up
    to 32 MB), and later blocks below it come from the heap, which keeps the memory after
    they are freed: the 1,000,000-face design held 515 MB of the 200 MB it had built, and
    every stage after it started from there.  Setting the threshold (``mallopt``,
    ``M_MMAP_THRESHOLD``) turns that off.  Elsewhere (no glibc) this does nothing."""
    import ctypes

    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return
    mallopt(-3, MMAP_THRESHOLD)   # M_MMAP_THRESHOLD (malloc.h)
