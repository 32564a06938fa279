"""``foldfab design``, ``export`` and ``preview``: a job's design files, its plotter program,
and the program's dry run, each written once the whole job is built."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from foldfab.cli.common import (_add_max_faces, _add_scale_arg, _add_split_args, _check_folder, _check_output,
                                _design, _fabricate_sheets, _write_preview, fabrication_report, format_report,
                                sheet_paths)


def _design_outputs(args: argparse.Namespace) -> list[tuple[str, Path]]:
    outputs = [(kind, Path(path)) for kind, path in
               (("fold", args.fold), ("svg", args.svg), ("cp", args.cp), ("mesh", args.mesh)) if path]
    from foldfab.errors import FoldfabError
    from foldfab.formats.output import MESH_SUFFIXES

    for kind, path in outputs:
        if kind == "mesh" and path.suffix.lower() not in MESH_SUFFIXES:
            raise FoldfabError(f"--mesh {path}: unknown mesh format {path.suffix!r}; use one of {', '.join(MESH_SUFFIXES)}")
        _check_folder(path, f"--{kind}")
    return outputs


def cmd_design(args: argparse.Namespace) -> int:
    """Build a design; print its summary and write the requested files."""
    from foldfab.design import summary
    from foldfab.fabrication.pieces import piece_design
    from foldfab.formats.output import write_design_files

    outputs = _design_outputs(args)
    design = _design(args)
    pieces = _pieces(design)   # each piece as files of its own beside the whole design's (not the mesh: one model)
    parts = [(piece_design(design, p), [(kind, sheet_paths(path, len(pieces))[p.number - 1])
                                        for kind, path in outputs if kind != "mesh"]) for p in pieces]
    files = [*outputs, *(file for _, part_files in parts for file in part_files)]
    try:
        write_design_files(design, outputs, parts)
    except OSError as exc:  # e.g. the path is a folder or not writable: one line, and every file as it was
        from foldfab.errors import FoldfabError

        kind, path = next(((k, p) for k, p in files if str(p) == exc.filename), files[0])
        raise FoldfabError(f"--{kind} {path}: cannot write: {exc.strerror or exc}") from None
    info = summary(design)
    info["pieces"] = len(pieces)
    info["written"] = [str(p) for _, p in files]
    for warning in design.warnings:
        print(f"foldfab: warning: {warning}", file=sys.stderr)
    if args.json:
        print(json.dumps(info, indent=2))
    else:
        print(format_summary(info))
    return 0


def _pieces(design) -> list:
    """The pieces of a split design ([fabrication].split), fitted to [fabrication].sheet for "auto"."""
    from foldfab.fabrication.pieces import design_pieces
    from foldfab.fabrication.spec import job_spec

    spec = job_spec(design.job)
    return design_pieces(design, spec, spec.sheet)


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
    if info.get("pieces"):
        lines.append(f"pieces       {info['pieces']} ([fabrication].split), each with its own files")
    for path in info.get("written", []):
        lines.append(f"wrote        {path}")
    return "\n".join(lines)


PROGRAM_SUFFIXES = {"hpgl": (".hpgl", ".plt", ".hpg"), "gcode": (".gcode", ".nc", ".gc", ".ngc"), "ebb": (".ebb",),
                    "gpgl": (".gpgl", ".gp")}


def cmd_export(args: argparse.Namespace) -> int:
    """Write the plotter program of a job for a device: streamed into a temporary file beside
    each output as it is written (never whole in memory), renamed into place once every
    sheet's program is written and its report made (with ``--verify``, from the file read back)."""
    from dataclasses import replace

    from foldfab.atomic import stream_files
    from foldfab.devices import load_device
    from foldfab.programs.languages import write_program

    output = Path(args.output)
    device = load_device(args.device)
    _check_output(output, "-o", PROGRAM_SUFFIXES[device.protocol])
    _, device, fabs = _fabricate_sheets(args, args.one_program, write=False)
    fabs = [fab.without_layout() for fab in fabs]   # a large design's peak is in the writing and the report
    paths = sheet_paths(output, len(fabs))
    infos = []
    with stream_files(paths) as files:   # nothing replaced unless every sheet is written and verified
        for number, file in enumerate(files):
            fab = fabs[number] = replace(fabs[number], program=write_program(fabs[number].plan, device, file.write))
            read_back = args.verify or fab.program.recording is None   # else the report is the writer's record
            program = replace(fab.program, text=file.read().decode("ascii")) if read_back else fab.program
            infos.append(fabrication_report(replace(fab, program=program), device, args.verify))
    _report(args, device, fabs, paths, infos)
    return 0


def _report(args: argparse.Namespace, device, fabs: list, paths: list[Path], infos: list | None = None) -> None:
    """Print the fabrication report of each sheet (one, unless the design is split)."""
    infos = infos or [fabrication_report(fab, device) for fab in fabs]
    for path, info in zip(paths, infos):
        info["written"] = str(path)
    if args.json:
        print(json.dumps(infos[0] if len(infos) == 1 else {"sheets": infos}, indent=2))
        return
    for number, info in enumerate(infos, 1):
        head = f"sheet        {number} of {len(infos)}\n" if len(infos) > 1 else ""
        print(head + format_report(info) + f"\nwrote        {info['written']}")


def cmd_preview(args: argparse.Namespace) -> int:
    """Render the dry run: the program read back and drawn as the machine would move."""
    output = Path(args.output)
    _check_output(output, "-o", (".svg",))
    _, device, fabs = _fabricate_sheets(args, args.one_program)
    paths = sheet_paths(output, len(fabs))
    for path, fab in zip(paths, fabs):
        _write_preview(fab, device, path)
    _report(args, device, fabs, paths)
    return 0


def _add_fabrication_args(parser: argparse.ArgumentParser, output_help: str) -> None:
    parser.add_argument("job", help="job file (TOML)")
    parser.add_argument("--device", required=True, metavar="NAME",
                        help="device profile: a built-in name, a profile in your config folder, or a .toml path")
    parser.add_argument("-o", "--output", required=True, metavar="OUT", help=output_help)
    parser.add_argument("--allow-penetration", action="store_true", help="fabricate a design whose faces intersect")
    _add_max_faces(parser)
    parser.add_argument("--json", action="store_true", help="print the report as JSON")
    _add_scale_arg(parser)
    _add_split_args(parser)


def add_commands(sub) -> None:
    """``foldfab design``, ``export`` and ``preview``."""
    design = sub.add_parser("design", help="build a design: summary, FOLD, SVG, ORIPA .cp, mesh",
                            description="Build the crease pattern and 3D model of a job file.")
    design.add_argument("job", help="job file (TOML)")
    design.add_argument("--fold", metavar="OUT.fold", help="write the crease pattern and folded form as FOLD")
    design.add_argument("--svg", metavar="OUT.svg", help="write the crease pattern as SVG (Origami Simulator colours)")
    design.add_argument("--cp", metavar="OUT.cp", help="write the crease pattern as ORIPA .cp")
    design.add_argument("--mesh", metavar="OUT", help="write the 3D model (.stl, .obj, .ply or .glb)")
    design.add_argument("--allow-penetration", action="store_true",
                        help="build a design whose faces intersect, with a warning instead of an error")
    _add_max_faces(design)
    design.add_argument("--json", action="store_true", help="print the summary as JSON")
    design.set_defaults(func=cmd_design, collect=False)   # builds one thing and exits (see cli.run)

    export = sub.add_parser("export", help="write the plotter program (HPGL or G-code) for a device",
                            description="Score and cut a design: write the program a plotter receives.")
    export.add_argument("--verify", action="store_true",
                        help="read the written program back and refuse it unless it draws what was planned "
                             "(report and estimate from the read-back; slower: foldfab plot always does it)")
    _add_fabrication_args(export, "program file (.hpgl/.plt for HPGL devices, .gcode/.nc for G-code, .ebb for EBB, "
                                  ".gpgl for GP-GL)")
    export.set_defaults(func=cmd_export, collect=False)   # builds one thing and exits (see cli.run)

    preview = sub.add_parser("preview", help="dry run: render what the plotter would do as SVG",
                             description="Read the program back and draw it: strokes per layer, travel, "
                                         "sheet, plottable area, pauses, and the time estimate.")
    _add_fabrication_args(preview, "preview SVG file")
    preview.set_defaults(func=cmd_preview, collect=False)   # builds one thing and exits (see cli.run)
