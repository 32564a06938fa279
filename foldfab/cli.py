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
    written: list[Path] = []
    try:
        for kind, path in outputs:
            write_design_file(design, kind, path)
            written.append(path)
    except OSError as exc:  # e.g. the path is a folder or not writable: one line, and no partial set of files
        from foldfab.errors import FoldfabError

        for done in written:
            done.unlink(missing_ok=True)
        raise FoldfabError(f"--{kind} {path}: cannot write: {exc.strerror or exc}") from None
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


PROGRAM_SUFFIXES = {"hpgl": (".hpgl", ".plt", ".hpg"), "gcode": (".gcode", ".nc", ".gc", ".ngc")}


def _fabricate(args: argparse.Namespace):
    """Design, device profile and fabrication of the command's job."""
    from foldfab.design import load_design
    from foldfab.devices import load_device
    from foldfab.fabrication import fabricate

    device = load_device(args.device)
    design = load_design(args.job, allow_penetration=args.allow_penetration)
    for warning in design.warnings:
        print(f"foldfab: warning: {warning}", file=sys.stderr)
    return design, device, fabricate(design, device)


def _check_output(path: Path, option: str, suffixes: tuple[str, ...]) -> None:
    from foldfab.errors import FoldfabError

    if path.suffix.lower() not in suffixes:
        raise FoldfabError(f"{option} {path}: expected a file ending in {', '.join(suffixes)}")
    if str(path.parent) and not path.parent.exists():
        raise FoldfabError(f"{option} {path}: folder {path.parent} does not exist; create it first")


def fabrication_report(fab, device) -> dict:
    """Per-layer lengths, travel before/after optimization and the time estimate of a fabrication."""
    from foldfab.estimate import estimate
    from foldfab.interpret import interpret

    run = interpret(fab.program, device, fab.plan.sheet)
    times = estimate(run, device)
    return {
        "device": device.name,
        "strategy": fab.spec.strategy,
        "sheet_mm": list(fab.plan.sheet),
        "optimize": fab.spec.optimize,
        "layers": {name: {"drawn_mm": round(t.drawn_length, 1), "pen_lifts": t.pen_lifts,
                          "travel_mm": round(t.travel_length, 1), "time_s": round(t.time, 1)}
                   for name, t in times.layers.items()},
        "travel_mm": {"before": {k: round(v, 1) for k, v in fab.travel_before["layers"].items()},
                      "after": {k: round(v, 1) for k, v in fab.travel_after["layers"].items()},
                      "total_before": round(fab.travel_before["total"], 1),
                      "total_after": round(fab.travel_after["total"], 1)},
        "pauses": [p.message for p in run.pauses],
        "estimated_time_s": round(times.total, 1),
        "lower_bound_s": round(times.lower_bound, 1),
        "program_bytes": len(fab.program.text),
    }


def format_report(info: dict) -> str:
    """Human-readable fabrication report."""
    lines = [f"device       {info['device']}  strategy {info['strategy']}  sheet {info['sheet_mm'][0]:g} x {info['sheet_mm'][1]:g} mm"]
    for name, layer in info["layers"].items():
        lines.append(f"{name:<12} {layer['drawn_mm']:>9.1f} mm drawn {layer['pen_lifts']:>6} pen lifts "
                     f"{layer['travel_mm']:>9.1f} mm travel {layer['time_s']:>8.1f} s")
    before, after = info["travel_mm"]["before"], info["travel_mm"]["after"]
    lines.append(f"pen-up travel ({info['optimize']}): {info['travel_mm']['total_before']:.1f} mm -> "
                 f"{info['travel_mm']['total_after']:.1f} mm")
    for key in after:
        lines.append(f"  {key:<16} {before.get(key, 0.0):>10.1f} -> {after[key]:>10.1f} mm")
    for message in info["pauses"]:
        lines.append(f"pause        {message}")
    lines.append(f"estimate     {info['estimated_time_s']:.1f} s (lower bound {info['lower_bound_s']:.1f} s)")
    return "\n".join(lines)


def cmd_export(args: argparse.Namespace) -> int:
    """Write the plotter program of a job for a device."""
    from foldfab.atomic import write_text
    from foldfab.devices import load_device

    output = Path(args.output)
    device = load_device(args.device)
    _check_output(output, "-o", PROGRAM_SUFFIXES[device.protocol])
    design, device, fab = _fabricate(args)
    info = fabrication_report(fab, device)
    write_text(output, fab.program.text)
    info["written"] = str(output)
    print(json.dumps(info, indent=2) if args.json else format_report(info) + f"\nwrote        {output}")
    return 0


def cmd_preview(args: argparse.Namespace) -> int:
    """Render the dry run: the program read back and drawn as the machine would move."""
    from foldfab.atomic import write_text
    from foldfab.interpret import interpret
    from foldfab.preview import render_preview

    output = Path(args.output)
    _check_output(output, "-o", (".svg",))
    design, device, fab = _fabricate(args)
    svg = render_preview(interpret(fab.program, device, fab.plan.sheet), device, fab.plan)
    write_text(output, svg)
    info = fabrication_report(fab, device)
    info["written"] = str(output)
    print(json.dumps(info, indent=2) if args.json else format_report(info) + f"\nwrote        {output}")
    return 0


def _add_fabrication_args(parser: argparse.ArgumentParser, output_help: str) -> None:
    parser.add_argument("job", help="job file (TOML)")
    parser.add_argument("--device", required=True, metavar="NAME",
                        help="device profile: a built-in name, a profile in your config folder, or a .toml path")
    parser.add_argument("-o", "--output", required=True, metavar="OUT", help=output_help)
    parser.add_argument("--allow-penetration", action="store_true", help="fabricate a design whose faces intersect")
    parser.add_argument("--json", action="store_true", help="print the report as JSON")


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

    export = sub.add_parser("export", help="write the plotter program (HPGL or G-code) for a device",
                            description="Score and cut a design: write the program a plotter receives.")
    _add_fabrication_args(export, "program file (.hpgl/.plt for HPGL devices, .gcode/.nc for G-code)")
    export.set_defaults(func=cmd_export)

    preview = sub.add_parser("preview", help="dry run: render what the plotter would do as SVG",
                             description="Read the program back and draw it: strokes per layer, travel, "
                                         "sheet, plottable area, pauses, and the time estimate.")
    _add_fabrication_args(preview, "preview SVG file")
    preview.set_defaults(func=cmd_preview)
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
