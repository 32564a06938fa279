"""``foldfab studio``: the four-view designer served on 127.0.0.1, in the browser."""

from __future__ import annotations

import argparse
from pathlib import Path


def cmd_studio(args: argparse.Namespace) -> int:
    """Serve the four-view designer on 127.0.0.1 and open a browser on it."""
    from foldfab.studio.api import Studio
    from foldfab.studio.server import serve

    studio = Studio(Path.cwd(), Path(args.job) if args.job else None)
    if args.job and not Path(args.job).exists():
        print(f"foldfab studio: {args.job} does not exist yet: a new design, saved there when you save")
    try:
        serve(studio, args.port, not args.no_browser,
              announce=lambda url: print(f"foldfab studio: {url}  (Ctrl-C stops)", flush=True))
    except KeyboardInterrupt:
        print("\nfoldfab studio: stopped")
    return 0


def _port_number(text: str) -> int:
    value = int(text)
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"expected 0 to 65535, got {value}")
    return value


def add_commands(sub) -> None:
    studio = sub.add_parser("studio", help="the four-view designer in the browser",
                            description="Design interactively: profile, trajectory (top view), crease pattern "
                                        "and 3D model, updated while you drag; open and save job files, export, "
                                        "dry-run preview and queue.  Serves on 127.0.0.1 only.  A relative file "
                                        "path typed in the studio starts in the current folder and must stay "
                                        "inside it or the job's folder; an absolute path may go anywhere.")
    studio.add_argument("job", nargs="?", metavar="JOB.toml", help="job file to open (a new design if it does not exist)")
    studio.add_argument("--port", type=_port_number, default=0, metavar="N", help="port (default 0: a free one)")
    studio.add_argument("--no-browser", action="store_true", help="only print the address; do not open a browser")
    studio.set_defaults(func=cmd_studio)
