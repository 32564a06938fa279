"""The ``foldfab`` command line: parses arguments, calls the library, prints.

Every command is a thin layer over library functions, in one module per command group:
:mod:`~foldfab.cli.design` (design, export, preview), :mod:`~foldfab.cli.plot`, :mod:`~foldfab.cli.printing`,
:mod:`~foldfab.cli.queue`, :mod:`~foldfab.cli.sim` and :mod:`~foldfab.cli.studio`, each adding
its subcommands to the parser built here; what several share is in :mod:`~foldfab.cli.common`.
Heavy modules (numpy, trimesh, vpype) are imported inside the command functions so
``foldfab --help`` stays fast.  A :class:`~foldfab.errors.FoldfabError` becomes one line on
stderr and exit code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import sys

from foldfab.cli import design, devices, plot, printing, profile, queue, sim, studio


GROUPS = {"design": design, "export": design, "preview": design, "devices": devices, "ports": devices, "plot": plot,
          "print": printing, "profile": profile, "queue": queue, "sim": sim, "studio": studio}
"""The module that adds each command to the parser (in the order ``foldfab --help`` lists them)."""


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The argument parser of every command; given ``command`` (a command's name, the first
    argument), of that command's group alone: it parses that command's arguments as the whole
    parser does, and building the other groups' parsers cost milliseconds of every start-up."""
    from foldfab import __version__

    parser = argparse.ArgumentParser(
        prog="foldfab",
        description="Mirror-reflection column origami: from a profile and a trajectory to a crease pattern, "
                    "a 3D model and a plotter program.")
    parser.add_argument("--version", action="version", version=f"foldfab {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    for group in [GROUPS[command]] if command in GROUPS else dict.fromkeys(GROUPS.values()):
        group.add_commands(sub)
    return parser


def run() -> int:
    """The ``foldfab`` console script and ``python -m foldfab``: :func:`main` on ``sys.argv``.

    On the way out the interpreter would run one last garbage collection over every
    object still alive (numpy, scipy and vpype's modules included: 30-60 ms, more after
    a large job) only to free memory the process is handing back anyway.  ``gc.freeze``
    exempts them; every file foldfab writes is closed (and atomically renamed) before
    ``main`` returns, so no finalizer is waited for.

    The cyclic collector is off while the parser is built, and stays off through a command
    that builds one thing and exits (``collect=False`` in its parser's defaults: design,
    export, preview, print).  Loading numpy, scipy, vpype and foldfab creates some hundred
    thousand objects, none of them garbage, and the collector traverses them again and again
    as they grow (about 30 ms of CPU of a paper-scale export, 6% of ``import vpype``;
    Mercurial turns it off for bulk work likewise).  Reference counting still frees all
    but cycles, and these commands make few (the 1,001,000-face ``design --fold`` and
    export peak at the same memory either way).  A command that runs on (plotting, the
    queue, the studio) collects as usual.
    """
    import gc
    import os

    # numpy's and scipy's OpenBLAS each start a thread per core that spins while idle (0.2 s of
    # CPU at every start, 0.4 s over a large export); foldfab's matrices are 3 x 3 and never
    # need them.  A user's own setting wins.
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    gc.disable()
    code = main()
    gc.freeze()
    return code


def main(argv: list[str] | None = None) -> int:
    """Parse ``argv`` (default ``sys.argv``), run the command; the exit code.  The cyclic
    collector runs for every command but those parsed with ``collect=False`` (see :func:`run`)."""
    argv = sys.argv[1:] if argv is None else argv
    parser = build_parser(argv[0] if argv else None)   # not a command name (--help, a typo): every command
    args = parser.parse_args(argv)
    if getattr(args, "collect", True):
        import gc

        gc.enable()
    else:
        _keep_freed_memory()
    from foldfab.errors import FoldfabError

    try:
        return args.func(args)
    except FoldfabError as exc:
        print(f"foldfab: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("foldfab: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader went away (``foldfab queue list | head``): not an error of ours.
        # Point stdout at /dev/null so the interpreter's final flush stays quiet.
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:  # the system refused (no room, no permission): one line, as for a mistake
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"foldfab: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2


def _keep_freed_memory() -> None:
    """Have glibc's allocator keep 64 MB spare at the top of the heap of a one-shot command.

    A large export frees and allocates arrays of megabytes over and over; by default each
    free hands the heap's top back to the system and the next allocation faults it in again,
    page by page (0.55-0.70 s of system time in the 100,000-face export; 0.16-0.20 s with the
    pad, for 22 MB more peak memory).  ``mallopt`` is glibc's; elsewhere nothing changes."""
    import ctypes

    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return
    mallopt(-2, 64 << 20)  # M_TOP_PAD, malloc.h
