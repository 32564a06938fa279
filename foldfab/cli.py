"""The ``foldfab`` command line: parses arguments, calls the library, prints.

Every command is a thin layer over library functions.  Heavy modules (numpy,
trimesh, vpype) are imported inside the command functions so ``foldfab --help``
stays fast.  A :class:`~foldfab.errors.FoldfabError` becomes one line on stderr
and exit code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

MESH_SUFFIXES = (".stl", ".obj", ".ply", ".glb")


def _design_outputs(args: argparse.Namespace) -> list[tuple[str, Path]]:
    outputs = [(kind, Path(path)) for kind, path in
               (("fold", args.fold), ("svg", args.svg), ("cp", args.cp), ("mesh", args.mesh)) if path]
    from foldfab.errors import FoldfabError

    for kind, path in outputs:
        if kind == "mesh" and path.suffix.lower() not in MESH_SUFFIXES:
            raise FoldfabError(f"--mesh {path}: unknown mesh format {path.suffix!r}; use one of {', '.join(MESH_SUFFIXES)}")
        if not path.parent.exists() and str(path.parent):
            raise FoldfabError(f"--{kind} {path}: folder {path.parent} does not exist; create it first")
    return outputs


def cmd_design(args: argparse.Namespace) -> int:
    """Build a design; print its summary and write the requested files."""
    from foldfab.design import load_design, summary
    from foldfab.output import write_design_file

    outputs = _design_outputs(args)
    design = load_design(args.job, allow_penetration=args.allow_penetration)
    for kind, path in outputs:
        write_design_file(design, kind, path)
    info = summary(design)
    info["written"] = [str(p) for _, p in outputs]
    for warning in design.warnings:
        print(f"foldfab: warning: {warning}", file=sys.stderr)
    if args.json:
        print(json.dumps(info, indent=2))
    else:
        print(format_summary(info))
    return 0


def format_summary(info: dict) -> str:
    """Human-readable summary of a design."""
    lines = [
        f"design       {info['name']}  ({info['job']})",
        f"trajectory   {'closed' if info['closed'] else 'open'}, {info['corners']} corners",
        f"line elements {info['line_elements']}, faces {info['faces']}, vertices {info['vertices']}",
    ]
    for label in ("mountain", "valley", "flat", "border"):
        c = info["creases"][label]
        lines.append(f"{label:<12} {c['count']:>7} edges  {c['length_mm']:>12.1f} mm")
    w, h = info["sheet_mm"]
    lines.append(f"sheet        {w:.1f} x {h:.1f} mm")
    lines.append(f"penetrations {info['penetrations']}")
    for path in info.get("written", []):
        lines.append(f"wrote        {path}")
    return "\n".join(lines)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of every command."""
    from foldfab import __version__

    parser = argparse.ArgumentParser(
        prog="foldfab",
        description="Mirror-reflection column origami: from a profile and a trajectory to a crease pattern, "
                    "a 3D model and a plotter program.")
    parser.add_argument("--version", action="version", version=f"foldfab {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    design = sub.add_parser("design", help="build a design: summary, FOLD, SVG, ORIPA .cp, mesh",
                            description="Build the crease pattern and 3D model of a job file.")
    design.add_argument("job", help="job file (TOML)")
    design.add_argument("--fold", metavar="OUT.fold", help="write the crease pattern and folded form as FOLD")
    design.add_argument("--svg", metavar="OUT.svg", help="write the crease pattern as SVG (Origami Simulator colours)")
    design.add_argument("--cp", metavar="OUT.cp", help="write the crease pattern as ORIPA .cp")
    design.add_argument("--mesh", metavar="OUT", help="write the 3D model (.stl, .obj, .ply or .glb)")
    design.add_argument("--allow-penetration", action="store_true",
                        help="build a design whose faces intersect, with a warning instead of an error")
    design.add_argument("--json", action="store_true", help="print the summary as JSON")
    design.set_defaults(func=cmd_design)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``foldfab`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    from foldfab.errors import FoldfabError

    try:
        return args.func(args)
    except FoldfabError as exc:
        print(f"foldfab: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("foldfab: interrupted", file=sys.stderr)
        return 130
