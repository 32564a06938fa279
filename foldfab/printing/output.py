"""Writing a template: a PDF of every page, or one SVG file per page, atomically."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

from foldfab.atomic import write_bytes, write_files
from foldfab.fabrication.pieces import design_pieces
from foldfab.fabrication.spec import job_spec
from foldfab.geometry.split import Piece
from foldfab.printing.paper import PrintOptions
from foldfab.printing.template import Template, build_template

SUFFIXES = (".pdf", ".svg")


def svg_paths(path: Path, count: int) -> list[Path]:
    """The files of a template of ``count`` pages written as SVG: ``name-1.svg``, ... ."""
    return [path.with_name(f"{path.stem}-{i}{path.suffix}") for i in range(1, count + 1)]


def template_pieces(design, options: PrintOptions, split: str | None = None) -> list[Piece]:
    """The pieces a template prints: the job's ``[fabrication].split`` (``split``, the command
    line's ``--split``, instead), cut by :func:`~foldfab.fabrication.pieces.design_pieces` as
    for the plotter, at the printed scale; "auto" fits them to ``[fabrication].sheet``, or to the
    printer's paper when the job names no sheet.  [] when the design is printed whole."""
    spec = replace(job_spec(design.job), scale=options.scale)
    if split is not None:
        spec = replace(spec, split=split)
    return design_pieces(design, spec, spec.sheet or options.paper)


def write_template(design, path: str | Path, options: PrintOptions,
                   pieces: Sequence[Piece] = ()) -> tuple[Template, list[Path]]:
    """Lay out ``design``'s template (its ``pieces`` when it is split) and write it to ``path``
    (``.pdf``, or ``.svg``: one file per page beside it); every file whole or none.  The
    template and the files written."""
    path = Path(path)
    template = build_template(design, options, pieces)
    if path.suffix.lower() == ".svg":
        from foldfab.printing.svg import render_svg

        paths = svg_paths(path, len(template.pages))
        write_files([(p, render_svg(page).encode()) for p, page in zip(paths, template.pages)])
        return template, paths
    from foldfab.printing.pdf import render_pdf

    write_bytes(path, render_pdf(template.pages, design.job.name))
    return template, [path]
