"""``foldfab print``: a job's crease pattern as a printable template (PDF, or SVG pages) at
true size, tiled across pages of the chosen paper, for folding by hand.

Named ``printing`` rather than ``print``: a submodule becomes an attribute of its package,
so ``foldfab/cli/print.py`` would shadow the built-in ``print`` inside ``foldfab.cli``."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from foldfab.cli.common import _add_max_faces, _add_split_args, _check_output, _design


def cmd_print(args: argparse.Namespace) -> int:
    """Write the printable template of a job."""
    from foldfab.errors import FoldfabError
    from foldfab.job import load_job
    from foldfab.printing.output import SUFFIXES, template_pieces, write_template
    from foldfab.printing.paper import PrintOptions, check_options, job_print_scale, parse_paper

    output = Path(args.output)
    _check_output(output, "-o", SUFFIXES)
    paper, name, turnable = parse_paper(args.paper)
    scale = args.scale if args.scale is not None else job_print_scale(load_job(args.job))
    options = PrintOptions(paper, name, turnable, args.margin, args.overlap, scale, args.flat, args.mono)
    check_options(options)
    design = _design(args)
    pieces = template_pieces(design, options, args.split)
    try:
        template, written = write_template(design, output, options, pieces)
    except OSError as exc:
        raise FoldfabError(f"-o {output}: cannot write: {exc.strerror or exc}") from None
    tilings = template.tilings
    info = {"name": design.job.name, "pages": len(template.pages), "pieces": max(len(pieces), 1), "paper": name,
            "paper_mm": list(tilings[0].paper), "scale": scale,
            "tiles": [[t.rows, t.cols] for t in tilings], "written": [str(p) for p in written]}
    if args.json:
        print(json.dumps(info, indent=2))
    else:
        w, h = info["paper_mm"]
        tiles = ", ".join(f"{rows} x {cols}" for rows, cols in info["tiles"])
        pieces_text = f"{info['pieces']} pieces of " if pieces else ""
        print(f"template     {info['name']}: {info['pages']} pages of {name} ({w:g} x {h:g} mm), scale {scale:g}, "
              f"{pieces_text}{tiles} tiles after the first page")
        for path in written:
            print(f"wrote        {path}")
    return 0


def _mm(text: str) -> float:
    """An argparse type: a finite number of mm, 0 or more."""
    import math

    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of mm, got {text!r}") from None
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"expected a number of mm, 0 or more, got {text!r}")
    return value


def _scale(text: str) -> float:
    value = _mm(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text!r}")
    return value


def add_commands(sub) -> None:
    """``foldfab print``."""
    cmd = sub.add_parser("print", help="a printable template: the crease pattern at true size on paper pages (PDF, SVG)",
                         description="Print a job's crease pattern at true size, tiled across pages, in origami's "
                                     "line conventions (valley dashed, mountain dash-dot, cut solid), with the folded "
                                     "model and folding notes on the first page.")
    cmd.add_argument("job", help="job file (TOML)")
    cmd.add_argument("-o", "--output", required=True, metavar="OUT",
                     help="OUT.pdf, or OUT.svg: one SVG per page, OUT-1.svg, OUT-2.svg, ...")
    cmd.add_argument("--paper", default="A4", metavar="SIZE",
                     help='A4, A3, Letter (turned to landscape when that needs fewer pages; "A4 landscape" fixes it) '
                          'or "[width, height]" in mm (default A4)')
    cmd.add_argument("--margin", type=_mm, default=10.0, metavar="MM", help="unprinted border of each page (default 10)")
    cmd.add_argument("--overlap", type=_mm, default=6.0, metavar="MM",
                     help="pattern shared by neighbouring pages, to tape them (default 6)")
    cmd.add_argument("--scale", type=_scale, metavar="S",
                     help="print at this scale instead of the job's [fabrication].scale (1: true size; "
                          "a job's \"fit\" prints at 1)")
    cmd.add_argument("--flat", action="store_true", help="draw flat creases (no fold) in faint grey")
    cmd.add_argument("--mono", action="store_true", help="black lines only (styles still differ)")
    _add_split_args(cmd, one_program=False)
    cmd.add_argument("--allow-penetration", action="store_true", help="print a design whose faces intersect")
    _add_max_faces(cmd)
    cmd.add_argument("--json", action="store_true", help="print the report as JSON")
    cmd.set_defaults(func=cmd_print, collect=False)   # builds one thing and exits (see cli.run)
