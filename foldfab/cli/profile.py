"""``foldfab profile``: a job with a generated profile (sine, arc, spline, smoothed), kept valid."""

from __future__ import annotations

import argparse


def cmd_profile(args: argparse.Namespace) -> int:
    """Write the job with its profile's points replaced by a generator's (the studio's profile tools)."""
    from pathlib import Path

    from foldfab.atomic import write_text
    from foldfab.design import generated_profile
    from foldfab.errors import FoldfabError
    from foldfab.job import job_data, load_job, parse_job, toml_text

    job = load_job(args.job)
    points = generated_profile(job, args.kind, amplitude=args.amplitude, period=args.period, count=args.points,
                               height=args.height, passes=args.rounds)
    out = Path(args.output)
    if out.exists() and not args.force:
        raise FoldfabError(f"{out} exists; pass --force to replace it")
    data = job_data(job, out.parent)
    data["profile"] = {"points": points.round(6).tolist(), "offset": list(job.profile.offset)}
    text = toml_text(data)
    parse_job(text, out)   # the file reads back as a job before it is written
    write_text(out, text)
    print(f"{out}: {args.kind} profile of {len(points)} points, u {points[:, 0].min():.4g} to "
          f"{points[:, 0].max():.4g} mm, v {points[:, 1].min():.4g} to {points[:, 1].max():.4g} mm")
    return 0


def add_commands(sub) -> None:
    from foldfab.cli.common import _positive_int

    profile = sub.add_parser("profile", help="a job with a generated profile: sine, arc, spline or smoothed",
                             description="Replace the profile of JOB.toml by a generated one and write the job "
                                         "to -o: a sine wave or circular arcs (amplitude, period, points, height: "
                                         "by default the current profile's), a spline through the current "
                                         "points, or the current points smoothed.  Points are clamped to where "
                                         "the trajectory leaves them room, so the design is valid.")
    profile.add_argument("job", metavar="JOB.toml", help="the job whose trajectory and settings are kept")
    profile.add_argument("kind", choices=("sine", "arc", "spline", "smooth"), help="what to make")
    profile.add_argument("-o", "--output", required=True, metavar="OUT.toml", help="the job file to write")
    profile.add_argument("--amplitude", type=float, default=5.0, metavar="MM",
                         help="how far the wave or arc reaches from u = 0 (negative: inwards; default 5)")
    profile.add_argument("--period", type=float, default=20.0, metavar="MM",
                         help="height of one wave or arc (default 20)")
    profile.add_argument("--points", type=_positive_int, default=41, metavar="N", help="points to make (default 41)")
    profile.add_argument("--height", type=float, default=None, metavar="MM",
                         help="height of the profile (default: the current profile's)")
    profile.add_argument("--rounds", type=_positive_int, default=3, metavar="N", help="smoothing rounds (smooth; default 3)")
    profile.add_argument("--force", action="store_true", help="replace OUT.toml if it exists")
    profile.set_defaults(func=cmd_profile)
