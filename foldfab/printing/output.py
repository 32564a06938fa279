"""Writing a template: a PDF of every page, or one SVG file per page, atomically."""

from __future__ import annotations

from pathlib import Path

from foldfab.atomic import write_bytes, write_files
from foldfab.printing.paper import PrintOptions
from foldfab.printing.template import Template, build_template

SUFFIXES = (".pdf", ".svg")


def svg_paths(path: Path, count: int) -> list[Path]:
    """The files of a template of ``count`` pages written as SVG: ``name-1.svg``, ... ."""
    return [path.with_name(f"{path.stem}-{i}{path.suffix}") for i in range(1, count + 1)]


def write_template(design, path: str | Path, options: PrintOptions) -> tuple[Template, list[Path]]:
    """Lay out ``design``'s template and write it to ``path`` (``.pdf``, or ``.svg``: one file
    per page beside it); every file whole or none.  The template and the files written."""
    path = Path(path)
    template = build_template(design, options)
    if path.suffix.lower() == ".svg":
        from foldfab.printing.svg import render_svg

        paths = svg_paths(path, len(template.pages))
        write_files([(p, render_svg(page).encode()) for p, page in zip(paths, template.pages)])
        return template, paths
    from foldfab.printing.pdf import render_pdf

    write_bytes(path, render_pdf(template.pages, design.job.name))
    return template, [path]
