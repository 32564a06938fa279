"""What several commands share: the job's design and fabrication, the checks of output paths
said before any work is done, the fabrication report, the dry-run preview, and argument types.

Its own module so that every command module imports it and none imports another one or
:mod:`foldfab.cli` (whose :func:`~foldfab.cli.build_parser` imports them all)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def _design(args: argparse.Namespace):
    """The command's job read, every table checked ([fabrication] too), and its design built."""
    from foldfab.design import build_design
    from foldfab.fabrication.spec import job_spec
    from foldfab.job import load_job
    from foldfab.limits import release_large_blocks

    release_large_blocks()   # a large design's temporaries go back to the system: every later stage needs less
    job = load_job(args.job)
    job_spec(job)
    return build_design(job, allow_penetration=args.allow_penetration, max_faces=args.max_faces)


def _fabricate(args: argparse.Namespace):
    """Job, device profile and fabrication of the command's job: a split design's sheets
    in one program, with a pause to load each new sheet."""
    job, device, [fab] = _fabricate_sheets(args, one_program=True)
    return job, device, fab


def _fabricate_sheets(args: argparse.Namespace, one_program: bool = False, write: bool = True):
    """Job, device profile and the fabrication of each sheet of the command's job (one,
    unless it is split; ``one_program``: one for all of them; ``write``: with its program).

    The design goes once it is laid out: a large design's crease pattern and mesh would
    otherwise stay through the optimization, the program and the report, the command's peak."""
    from foldfab.devices import load_device
    from foldfab.fabricate import finish_sheets, lay_out_sheets

    device = load_device(args.device)
    design = _design(args)
    sheets = lay_out_sheets(design, device, scale=getattr(args, "scale", None), split=getattr(args, "split", None))
    job, warnings = design.job, design.warnings
    del design
    fabs = finish_sheets(sheets, device, one_program, write)
    for warning in (*warnings, *fabs[0].warnings):
        print(f"foldfab: warning: {warning}", file=sys.stderr)
    return job, device, fabs


def sheet_paths(path: Path, count: int) -> list[Path]:
    """Where the files of ``count`` sheets or pieces go: ``path`` itself for one, else
    ``name-1.ext``, ``name-2.ext``, ... beside it."""
    if count == 1:
        return [path]
    return [path.with_name(f"{path.stem}-{n}{path.suffix}") for n in range(1, count + 1)]


def _add_split_args(parser: argparse.ArgumentParser, one_program: bool = True) -> None:
    parser.add_argument("--split", choices=["auto"],
                        help="cut a design larger than the sheet into the fewest pieces that fit, joined by glue tabs "
                             "(instead of the job's [fabrication].split)")
    if one_program:
        parser.add_argument("--one-program", action="store_true",
                            help="a split design's sheets in one program, pausing to load each new sheet "
                                 "(default: one file per sheet, name-1, name-2, ...)")


def _check_output(path: Path, option: str, suffixes: tuple[str, ...]) -> None:
    from foldfab.errors import FoldfabError

    if path.suffix.lower() not in suffixes:
        raise FoldfabError(f"{option} {path}: expected a file ending in {', '.join(suffixes)}")
    _check_folder(path, option)


def _check_folder(path: Path, option: str) -> None:
    """An output path must name a file in a folder that exists: said before any work is done."""
    from foldfab.errors import FoldfabError

    if path.is_dir():
        raise FoldfabError(f"{option} {path}: is a folder; give the name of a file in it")
    if str(path.parent) and not path.parent.is_dir():
        what = "is a file, not a folder" if path.parent.exists() else "does not exist; create it first"
        raise FoldfabError(f"{option} {path}: folder {path.parent} {what}")


def fabrication_report(fab, device, verify: bool = False) -> dict:
    """Per-layer lengths, travel before/after optimization and the time estimate of a fabrication,
    from what its writer recorded; ``verify``: from the program read back, refused unless it
    draws what was recorded."""
    from foldfab.programs.estimate import estimate_drawn
    from foldfab.programs.interpret import drawn

    run = drawn(fab.program, device, fab.plan.sheet, verify)
    times = estimate_drawn(run, device)
    return {
        "device": device.name,
        "strategy": fab.spec.strategy,
        "sheet_mm": list(fab.plan.sheet),
        "optimize": fab.spec.optimize,
        "scale": fab.placement.scale,
        "scale_fitted": fab.spec.scale == "fit",
        "rotated": fab.placement.rotated,
        "warnings": list(fab.warnings),
        "blades": fab.blade_notes,
        "layers": {name: {"drawn_mm": round(t.drawn_length, 1), "pen_lifts": t.pen_lifts,
                          "travel_mm": round(t.travel_length, 1), "time_s": round(t.time, 1)}
                   for name, t in times.layers.items()},
        "travel_mm": {"before": {k: round(v, 1) for k, v in fab.travel_before["layers"].items()},
                      "after": {k: round(v, 1) for k, v in fab.travel_after["layers"].items()},
                      "total_before": round(fab.travel_before["total"], 1),
                      "total_after": round(fab.travel_after["total"], 1)},
        "pauses": list(run.pauses),
        "estimated_time_s": round(times.total, 1),
        "lower_bound_s": round(times.lower_bound, 1),
        "program_bytes": fab.program.size,
    }


def format_report(info: dict) -> str:
    """Human-readable fabrication report."""
    from foldfab.fabrication.spec import placement_text

    lines = [f"device       {info['device']}  strategy {info['strategy']}  sheet {info['sheet_mm'][0]:g} x {info['sheet_mm'][1]:g} mm",
             f"placement    {placement_text(info['scale'], info['scale_fitted'], info['rotated'])}"]
    lines += [f"blade        {note}" for note in info.get("blades", ())]
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


def _write_preview(fab, device, output: Path) -> None:
    """The dry-run SVG of a fabrication (``foldfab preview``, ``foldfab plot --preview``)."""
    from foldfab.atomic import write_text
    from foldfab.programs.interpret import interpret
    from foldfab.programs.preview import render_preview

    write_text(output, render_preview(interpret(fab.program, device, fab.plan.sheet), device, fab.plan,
                                      notes=[fab.placement_summary, *fab.blade_notes]))


def _add_scale_arg(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scale", type=_scale, metavar="S|fit",
                        help="scale of the design on the sheet instead of the job's [fabrication].scale: a number "
                             "> 0, or fit: the largest that fits the sheet and the device's reach")


def _scale(text: str) -> float | str:
    """An argparse type: ``fit`` or a finite number > 0."""
    import math

    if text == "fit":
        return text
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a number > 0 or fit, got {text!r}")
    return value


def _add_max_faces(parser: argparse.ArgumentParser) -> None:
    from foldfab.limits import MAX_FACES

    parser.add_argument("--max-faces", type=_positive_int, metavar="N",
                        help=f"build a design of up to N faces (default: the job's [design].max_faces, "
                             f"else {MAX_FACES:,})")


def _positive_int(text: str) -> int:
    """An argparse type: a whole number, 1 or more."""
    return _int_from(1, None, "expected a whole number")(text)


def _int_from(low: int, high: int | None, what: str):
    """An argparse type: a whole number from ``low`` to ``high`` (None: no upper bound)."""
    def whole(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
        if value < low or (high is not None and value > high):
            bounds = f"from {low} to {high}" if high is not None else f"of {low} or more"
            raise argparse.ArgumentTypeError(f"{what} {bounds}, got {value}")
        return value
    return whole
